"""The published real datasets: where they come from, pinned by sha256 and the source commit,
and where a fetched copy lives (`macrostate-mj data fetch`, with `pooch`).

A fetched copy sits under the reference-data root at the same relative paths as in the
publishing repository (`<root>/ReTLo/Datasets/3Robots/Train.csv`), so `--real` defaults and
`$MACROSTATE_REFERENCE_DATA` read it alike. A file already present with the pinned hash is not
downloaded again (a second fetch is a no-op, an interrupted one resumes file by file); a
download whose hash differs is refused and removed (pooch downloads to a temporary file and
moves it in only once verified). The held-out test files are fetched and verified like the
rest: the project never trains, tunes or reports on them.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

from macrostate_mj.core.errors import RunFailure, UserError
from macrostate_mj.core.io import write_json_atomic

CACHE_ENV = "MACROSTATE_DATA_CACHE"       # where `data fetch` puts files by default
VERIFIED = ".verified.json"      # written in a dataset's folder once all its files are verified


@dataclass(frozen=True)
class Dataset:
    """One published dataset: its repository and commit, its folder under the reference-data
    root, and every file by its path in the repository and sha256."""

    name: str
    repo: str                   # GitHub owner/name
    commit: str
    folder: str
    files: Mapping[str, str]
    held_out: frozenset[str] = field(default_factory=frozenset)

    @property
    def base_url(self) -> str:
        """Where the files sit at their repository paths (the raw files of the commit)."""
        return f"https://raw.githubusercontent.com/{self.repo}/{self.commit}/"


RETLO = Dataset(
    "retlo", "ctyeong/ReTLo", "6e479578e90009b0e37ce0f7d5cb130d7dca0944", "ReTLo",
    {"Datasets/3Robots/Train.csv":
         "c3bde6555ba8582535445dee46c1079aea7324225d610d0d60dfd59a8231a1ad",
     "Datasets/3Robots/Val.csv":
         "f7abe22e47381864ba9b3e375844efed0444125d5308869eda7d7b0556049f1e",
     "Datasets/3Robots/Test.csv":
         "1456b01ca7caa130216086e230b4054ad8dd268790c53d1f4119ed5a3da0cd5b",
     "Datasets/5Robots/Test.csv":
         "71314f64e04286c90d8f90ba4352b7f120bc7a4f88f372034ae2a237244aeab8"},
    frozenset({"Datasets/3Robots/Test.csv", "Datasets/5Robots/Test.csv"}))

DATASETS: dict[str, Dataset] = {d.name: d for d in (RETLO,)}


def cache_root() -> Path:
    """Where `data fetch` puts datasets unless told: `$MACROSTATE_DATA_CACHE`, else the user's
    cache folder (what `pooch.os_cache` names, without importing pooch at every start)."""
    if env := os.environ.get(CACHE_ENV):
        return Path(env)
    from platformdirs import user_cache_path

    return user_cache_path("macrostate-mj")


def fetched(root: Path, folder: str) -> bool:
    """Whether `data fetch` verified every file of the dataset in `root / folder` (a fetch
    that stopped half way, or found the mirror unreachable, leaves no such mark)."""
    return (root / folder / VERIFIED).is_file()


def named(names: list[str]) -> list[Dataset]:
    """The datasets `names` call for (`all` for every one); one-line errors otherwise."""
    unknown = [n for n in names if n != "all" and n not in DATASETS]
    if unknown or not names:
        raise UserError(f"data fetch {' '.join(unknown) or '(nothing)'}: name one of "
                        f"{', '.join(DATASETS)} or all")
    return list(DATASETS.values()) if "all" in names else [DATASETS[n] for n in names]


def fetch(dataset: Dataset, root: Path, mirror: str | None = None, progress: bool = False
          ) -> list[Path]:
    """Every file of `dataset` under `root / dataset.folder`, downloaded from the commit's raw
    files (or `mirror`, under which they sit at the same relative paths) unless present with
    the pinned hash; each verified. Bad mirrors and hashes are `UserError`s, an unreachable
    default source a `RunFailure`; nothing unverified is left behind."""
    if mirror is not None and not mirror.startswith(("http://", "https://")):
        raise UserError(f"--mirror {mirror}: give a URL (http:// or https://)")
    import pooch
    import requests

    pooch.get_logger().setLevel("WARNING")      # its "Downloading ..." lines: the bar says it
    base = dataset.base_url if mirror is None else mirror.rstrip("/") + "/"
    store = pooch.create(path=root / dataset.folder, base_url=base,
                         registry={f: f"sha256:{h}" for f, h in dataset.files.items()})
    where = f"--mirror {mirror}" if mirror else f"{dataset.repo}@{dataset.commit[:7]}"
    got = []
    for name in dataset.files:
        try:
            path = Path(store.fetch(name, progressbar=progress))
        except ValueError as err:
            if "hash" not in str(err):
                raise
            raise UserError(f"{where}: {name} is not the published file ({str(err).split('.')[0]}"
                            "); nothing was kept. Check the mirror's copy") from None
        except requests.RequestException as err:
            reason = type(err).__name__
            if mirror is not None:
                raise UserError(f"--mirror {mirror}: {name} could not be fetched ({reason}); "
                                "give a base URL under which the files sit at their paths in "
                                f"{dataset.repo}") from None
            raise RunFailure(f"{dataset.repo}: {name} could not be fetched ({reason}); retry, "
                             "or pass --mirror URL") from None
        got.append(path)
    write_json_atomic(root / dataset.folder / VERIFIED,
                      {"repo": dataset.repo, "commit": dataset.commit, "files": dataset.files})
    return got
