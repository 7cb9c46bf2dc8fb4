"""`experiment retlo`'s results record: what its `results.json` holds, and its unit."""

from __future__ import annotations

from dataclasses import dataclass, field

from macrostate_mj.core.records import OPTIONAL, Record

CV_TEST = "cross-validated train + val"     # the name of the folds' test in `tests`


@dataclass(frozen=True)
class Results(Record):
    """Chapter 2's ReTLo errors per test set and model (per fold-seed and per robot and step),
    and Fig 2.9's curve analysis; each seed trains on its own data and is tested on its own
    block."""

    UNIT = "seed"

    px_per_cm: float
    seeds: list[int]
    tests: list[dict]
    results: dict[str, dict]
    fig2_9: dict | None = field(default=None, metadata=OPTIONAL)
