"""What the committed results show: the one registry of results sources (`sources`), the
dissertation's claims judged by one rule (`claims`, `claims.toml`) and each results folder's
provenance and kind (`provenance`, from `results/index.toml`).

The sources that read one experiment's records live beside that experiment; this package holds
the generic ones and what judges and labels them.
"""

from pathlib import Path

CLAIMS = Path(__file__).with_name("claims.toml")     # the claims, chapter by chapter
