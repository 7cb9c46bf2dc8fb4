"""The published real datasets: where they come from, pinned by sha256 and the source commit,
and where a fetched copy lives (`macrostate-mj data fetch`, with `pooch`).

A fetched copy sits under the reference-data root at the same relative paths as in the
publishing repository (`<root>/ReTLo/Datasets/3Robots/Train.csv`), so `--real` defaults and
`$MACROSTATE_REFERENCE_DATA` read it alike. Three kinds, chosen by their class:

- `Files`: each file downloaded from the commit's raw files, pinned by its sha256. A file
  already present with the pinned hash is not downloaded again (an interrupted fetch resumes
  file by file); a download whose hash differs is refused and removed (pooch downloads to a
  temporary file and moves it in only once verified).
- `Archive`: the repository's archive of the commit, for a dataset of too many files to fetch
  one by one (the ant flows: 159,810). GitHub does not promise an archive's bytes stay the same,
  so the pin is on content: each top folder's *tree digest* (`tree_digest`), checked on the
  extracted files before the folder is moved into place.
- `Subset`: files picked from a fetched dataset by a stated rule (the project's dev set of
  unstable ant flows), linked, not downloaded, and pinned by tree digest too.

A dataset's folder holds `.verified.json` once every file is verified, so a second fetch is a
no-op and a fetch cut short never shadows another copy. The held-out test files are fetched and
verified like the rest: the project never trains, tunes or reports on them.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import re
import shutil
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from macrostate_mj.core.errors import RunFailure, UserError
from macrostate_mj.core.io import write_json_atomic

CACHE_ENV = "MACROSTATE_DATA_CACHE"       # where `data fetch` puts files by default
VERIFIED = ".verified.json"      # written in a dataset's folder once all its files are verified


def tree_digest(folder: Path) -> str:
    """sha256 of the lines `<sha256 of file>  <path>` of every file under `folder`, sorted by
    path (relative to the folder's parent, POSIX form): one figure for a folder's exact content,
    the same as computed from the publishing repository's own files."""
    paths = sorted(p.relative_to(folder.parent).as_posix() for p in _files(folder))
    lines = (f"{_sha256(folder.parent / path)}  {path}\n" for path in paths)
    return hashlib.sha256("".join(lines).encode()).hexdigest()


def _files(folder: Path) -> Iterator[Path]:
    return (p for p in folder.rglob("*") if p.is_file())


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@dataclass(frozen=True)
class Dataset:
    """One published dataset: its repository and commit, and its folder under the
    reference-data root. Subclasses say how its files are got and verified."""

    name: str
    repo: str                   # GitHub owner/name
    commit: str
    folder: str
    held_out: frozenset[str] = field(default_factory=frozenset, kw_only=True)

    def fetch(self, root: Path, mirror: str | None = None, progress: bool = False) -> int:
        """Make `root / folder` hold the verified dataset, from the pinned source or `mirror`
        (a checked base URL); the number of its files."""
        count = self._fetch(root, mirror, progress)
        write_json_atomic(root / self.folder / VERIFIED,
                          {"repo": self.repo, "commit": self.commit, "count": count,
                           **self._pins()})
        return count

    def _fetch(self, root: Path, mirror: str | None, progress: bool) -> int:
        raise NotImplementedError

    def _pins(self) -> dict[str, Any]:
        raise NotImplementedError


@dataclass(frozen=True)
class Files(Dataset):
    """A dataset fetched file by file from the commit's raw files, each pinned by sha256."""

    files: Mapping[str, str] = field(default_factory=dict, kw_only=True)

    @property
    def base_url(self) -> str:
        return f"https://raw.githubusercontent.com/{self.repo}/{self.commit}/"

    def _pins(self) -> dict[str, Any]:
        return {"files": dict(self.files)}

    def _fetch(self, root: Path, mirror: str | None, progress: bool) -> int:
        import pooch

        store = pooch.create(path=root / self.folder, base_url=mirror or self.base_url,
                             registry={f: f"sha256:{h}" for f, h in self.files.items()})
        for name in self.files:
            with _download_errors(self, mirror, name):
                store.fetch(name, progressbar=progress)
        return len(self.files)


@dataclass(frozen=True)
class Archive(Dataset):
    """A dataset fetched as the repository's archive of the commit (`archive/<commit>.zip`
    under the repository's URL, as GitHub serves it), the top folders in `trees` extracted and
    each checked by its tree digest before the dataset's folder is moved into place."""

    trees: Mapping[str, str] = field(default_factory=dict, kw_only=True)

    @property
    def base_url(self) -> str:
        return f"https://github.com/{self.repo}/"

    @property
    def archive(self) -> str:
        return f"archive/{self.commit}.zip"

    def _pins(self) -> dict[str, Any]:
        return {"archive": self.archive, "trees": dict(self.trees)}

    def _fetch(self, root: Path, mirror: str | None, progress: bool) -> int:
        import zipfile

        import pooch

        target = root / self.folder
        if count := _marked(root, self):
            return count
        if target.exists():            # a copy placed by hand: adopt it if it is the dataset
            return _adopt(self, target, self.trees)
        downloads = root / ".downloads"
        with _download_errors(self, mirror, self.archive):
            got = Path(pooch.retrieve((mirror or self.base_url) + self.archive, known_hash=None,
                                      fname=f"{self.folder}-{self.commit}.zip",
                                      path=downloads, progressbar=progress))
        partial = root / f".{self.folder}.partial"
        shutil.rmtree(partial, ignore_errors=True)
        try:
            with zipfile.ZipFile(got) as zf:
                for info in zf.infolist():
                    # GitHub's archive holds one top folder, <repo name>-<commit>/
                    inner = info.filename.partition("/")[2]
                    if info.is_dir() or inner.split("/")[0] not in self.trees:
                        continue
                    dest = partial / inner
                    dest.parent.mkdir(parents=True, exist_ok=True)
                    with zf.open(info) as src, open(dest, "wb") as out:
                        shutil.copyfileobj(src, out)
            count = _check(self, partial, self.trees, mirror)
        except (zipfile.BadZipFile, UserError) as err:
            shutil.rmtree(partial, ignore_errors=True)
            got.unlink(missing_ok=True)
            if isinstance(err, UserError):
                raise
            raise _not_published(self, mirror, self.archive, "not a zip archive") from None
        partial.rename(target)
        got.unlink()
        with contextlib.suppress(OSError):          # other downloads may be under way there
            downloads.rmdir()
        return count


@dataclass(frozen=True)
class Subset(Dataset):
    """Files picked from another fetched dataset by `keep(path)` (paths as in that dataset's
    folder), hard-linked (copied where links cannot be made), pinned by tree digest."""

    source: Dataset | None = field(default=None, kw_only=True)
    keep: Callable[[str], bool] = field(default=lambda path: False, kw_only=True)
    rule: str = field(default="", kw_only=True)           # `keep` in words, for the mark
    trees: Mapping[str, str] = field(default_factory=dict, kw_only=True)

    def _pins(self) -> dict[str, Any]:
        return {"rule": self.rule, "trees": dict(self.trees)}

    def _fetch(self, root: Path, mirror: str | None, progress: bool) -> int:
        assert self.source is not None
        self.source.fetch(root, mirror, progress)
        target = root / self.folder
        if count := _marked(root, self):
            return count
        if target.exists():
            return _adopt(self, target, self.trees)
        origin = root / self.source.folder
        partial = root / f".{self.folder}.partial"
        shutil.rmtree(partial, ignore_errors=True)
        for path in sorted(_files(origin)):
            rel = path.relative_to(origin).as_posix()
            if self.keep(rel):
                dest = partial / rel
                dest.parent.mkdir(parents=True, exist_ok=True)
                try:
                    os.link(path, dest)
                except OSError:
                    shutil.copyfile(path, dest)
        try:
            count = _check(self, partial, self.trees, None)
        except UserError:
            shutil.rmtree(partial, ignore_errors=True)
            raise
        partial.rename(target)
        return count


def _base(mirror: str | None) -> str | None:
    """The mirror as a base URL (a dataset's files at their repository paths under it)."""
    if mirror is None:
        return None
    if not mirror.startswith(("http://", "https://")):
        raise UserError(f"--mirror {mirror}: give a URL (http:// or https://)")
    return mirror.rstrip("/") + "/"


@contextlib.contextmanager
def _download_errors(dataset: Dataset, mirror: str | None, name: str) -> Iterator[None]:
    """pooch's and requests' failures as one-line errors: a bad mirror or a file that is not
    the published one is the user's to fix (`UserError`), the default source unreachable not."""
    import requests

    try:
        yield
    except ValueError as err:
        if "hash" not in str(err):
            raise
        raise _not_published(dataset, mirror, name, str(err).split(".")[0]) from None
    except requests.RequestException as err:
        reason = type(err).__name__
        if mirror is not None:
            raise UserError(f"--mirror {mirror.rstrip('/')}: {name} could not be fetched "
                            f"({reason}); give a base URL under which the files sit at their "
                            f"paths in {dataset.repo}") from None
        raise RunFailure(f"{dataset.repo}: {name} could not be fetched ({reason}); retry, "
                         "or pass --mirror URL") from None


def _marked(root: Path, dataset: Dataset) -> int:
    """The file count `data fetch` recorded for `dataset` of its commit in `root`, else 0."""
    return int(_mark(root / dataset.folder).get("count", 0)) if fetched(
        root, dataset.folder, dataset.commit) else 0


def _mark(folder: Path) -> dict[str, Any]:
    return json.loads((folder / VERIFIED).read_text())


def _not_published(dataset: Dataset, mirror: str | None, name: str, why: str) -> UserError:
    where = (f"--mirror {mirror.rstrip('/')}" if mirror
             else f"{dataset.repo}@{dataset.commit[:7]}")
    fix = "Check the mirror's copy" if mirror else "Retry, or fetch from a copy with --mirror"
    return UserError(f"{where}: {name} is not the published file ({why}); nothing was kept. "
                     f"{fix}")


def _check(dataset: Dataset, folder: Path, trees: Mapping[str, str], mirror: str | None
           ) -> int:
    """The number of files in `folder` once each top folder's tree digest is the pinned one;
    otherwise a `UserError` naming the first that differs."""
    for top, digest in trees.items():
        if not (folder / top).is_dir() or tree_digest(folder / top) != digest:
            raise _not_published(dataset, mirror, f"{dataset.folder}/{top}",
                                 "its tree digest differs")
    return sum(1 for _ in _files(folder))


def _adopt(dataset: Dataset, target: Path, trees: Mapping[str, str]) -> int:
    """A dataset folder already there without the mark: kept if it is the published content,
    else refused (it may be the user's own files; nothing is overwritten)."""
    try:
        return _check(dataset, target, trees, None)
    except UserError:
        raise UserError(f"{target} holds files that are not {dataset.name}'s published ones; "
                        "move it away or fetch into another --dir") from None


RETLO = Files(
    "retlo", "ctyeong/ReTLo", "6e479578e90009b0e37ce0f7d5cb130d7dca0944", "ReTLo",
    files={"Datasets/3Robots/Train.csv":
           "c3bde6555ba8582535445dee46c1079aea7324225d610d0d60dfd59a8231a1ad",
           "Datasets/3Robots/Val.csv":
           "f7abe22e47381864ba9b3e375844efed0444125d5308869eda7d7b0556049f1e",
           "Datasets/3Robots/Test.csv":
           "1456b01ca7caa130216086e230b4054ad8dd268790c53d1f4119ed5a3da0cd5b",
           "Datasets/5Robots/Test.csv":
           "71314f64e04286c90d8f90ba4352b7f120bc7a4f88f372034ae2a237244aeab8"},
    held_out=frozenset({"Datasets/3Robots/Test.csv", "Datasets/5Robots/Test.csv"}))

# split*/test.csv and Unstable/ are the published test sets of the one-class task
HSANTS = Archive(
    "hsants", "ctyeong/OpticalFlows_HsAnts", "d82732749bc799aa1f7505c19e65e8c493a34e8f",
    "OpticalFlows_HsAnts",
    trees={"Stable": "739d3992a1c3acde04579252823655ab0c19d9f76ed7c53340550ca6f6001c7f",
           "Unstable": "e716a5b2b8697c62bb46232a418f5f38c4dffb5e3cf5cf2e26f746901c32cca6",
           "split1": "9e4b2376ce4e1f32e01c0a0f2586e172972c2ad821db49265dc4f7fa9290034f",
           "split2": "ae687dcee4359977a95fa55753b07a9983d4b03acb116921e5f40571ecfdb7cd",
           "split3": "b3fddff591e1f4ee3bcad4917a96e5ede8d810cd126740012b53295b8a86187d"},
    held_out=frozenset({"split1/test.csv", "split2/test.csv", "split3/test.csv", "Unstable"}))

_DEV = re.compile(r"Unstable/flow_[xy]_(\d+)-\d\.jpg")


def _every_tenth_unstable_flow(path: str) -> bool:
    match = _DEV.fullmatch(path)
    return match is not None and int(match[1]) >= 1338 and (int(match[1]) - 1338) % 10 == 0


# the dev set of real unstable flows (research decisions and reported figures, never model
# selection): every tenth sample from id 1338, so each time bin in its true proportion
HSANTS_DEV = Subset(
    "hsants-dev", HSANTS.repo, HSANTS.commit, "OpticalFlows_HsAnts-dev", source=HSANTS,
    keep=_every_tenth_unstable_flow,
    rule="Unstable flow_x/flow_y files of ids 1338, 1348, ... (every tenth from 1338)",
    trees={"Unstable": "cea0b8c47d758200b398827f3371d49d52f3e27fe0a4ab081983d9eaa8dc586a"})

DATASETS: dict[str, Dataset] = {d.name: d for d in (RETLO, HSANTS, HSANTS_DEV)}


def cache_root() -> Path:
    """Where `data fetch` puts datasets unless told: `$MACROSTATE_DATA_CACHE`, else the user's
    cache folder (what `pooch.os_cache` names, without importing pooch at every start)."""
    if env := os.environ.get(CACHE_ENV):
        return Path(env)
    from platformdirs import user_cache_path

    return user_cache_path("macrostate-mj")


def fetched(root: Path, folder: str, commit: str | None = None) -> bool:
    """Whether `data fetch` verified every file of the dataset in `root / folder` (of
    `commit`, when given); a fetch that stopped half way leaves no such mark."""
    if not (root / folder / VERIFIED).is_file():
        return False
    return commit is None or _mark(root / folder).get("commit") == commit


def named(names: list[str]) -> list[Dataset]:
    """The datasets `names` call for (`all` for every one); one-line errors otherwise."""
    unknown = [n for n in names if n != "all" and n not in DATASETS]
    if unknown or not names:
        raise UserError(f"data fetch {' '.join(unknown) or '(nothing)'}: name one of "
                        f"{', '.join(DATASETS)} or all")
    return list(DATASETS.values()) if "all" in names else [DATASETS[n] for n in names]


def fetch(dataset: Dataset, root: Path, mirror: str | None = None, progress: bool = False
          ) -> int:
    """`dataset` verified under `root / dataset.folder`, fetched from its pinned source (or
    `mirror`, a base URL under which its files sit at their repository paths) unless already
    there; the number of its files. Bad mirrors and content are `UserError`s, an unreachable
    default source a `RunFailure`; nothing unverified is left behind."""
    import pooch

    base = _base(mirror)                            # a bad --mirror before anything is made
    pooch.get_logger().setLevel("WARNING")      # its "Downloading ..." lines: the bar says it
    return dataset.fetch(root, base, progress)
