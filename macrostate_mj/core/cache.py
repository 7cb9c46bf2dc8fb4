"""One task cache: a task's output files kept under the hash of everything that made them.

A task's key hashes its stage's name and version, its config (canonical JSON) and the bytes of
its inputs (files, folders, arrays), so a changed config, a changed input file or a new version
of the stage's code gives a new key and the task is computed again; nothing is reused because
of a name alone. A task's outputs are files written into a temporary folder that is renamed
onto `<root>/<stage>/<key>/`: a key's folder is complete or absent, whatever killed the run.

Tasks run through one runner (`run_tasks`): in this process, on local worker processes
(`workers`) or on a Ray cluster (`ray`); the driver writes each result as it arrives, so a rerun
of the same command after a kill computes only what is missing, and tasks with the same key run
once. Nothing in a cache is unpickled: outputs are bytes that callers read as JSON, Parquet,
`.npz` (allow_pickle=False) or tensors (`torch.load(weights_only=True)`).
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import tempfile
from collections.abc import Callable, Hashable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar, Protocol

import numpy as np

from macrostate_mj.core.io import jsonable
from macrostate_mj.core.parallel import runner_for

Input = str | os.PathLike | bytes | np.ndarray


def task_key(stage: str, version: int, config: Any, inputs: Iterable[Input] = ()) -> str:
    """sha256 over the stage, its version, the config's canonical JSON and the inputs' bytes."""
    h = hashlib.sha256()
    h.update(json.dumps([stage, version, jsonable(config)], sort_keys=True,
                        separators=(",", ":")).encode())
    for item in inputs:
        _update(h, item)
    return h.hexdigest()


def _update(h: Any, item: Input) -> None:
    if isinstance(item, np.ndarray):
        h.update(f"array {item.dtype.str} {item.shape}".encode())
        h.update(np.ascontiguousarray(item).tobytes())
    elif isinstance(item, bytes):
        h.update(b"bytes %d " % len(item) + item)
    else:
        path = Path(item)
        files = sorted(p for p in path.rglob("*") if p.is_file()) if path.is_dir() else [path]
        for f in files:
            data = f.read_bytes()
            h.update(f"file {f.relative_to(path) if path.is_dir() else ''} {len(data)} ".encode())
            h.update(data)


class TaskCache:
    """Task outputs on disk, one folder per key under `<root>/<stage>/`."""

    def __init__(self, root: str | os.PathLike):
        self.root = Path(root)
        self.hits: list[str] = []     # keys found done (a resumed run's record)

    def folder(self, stage: str, key: str) -> Path:
        return self.root / stage / key

    def get(self, stage: str, key: str) -> Path | None:
        """The task's output folder if it is complete, else None."""
        folder = self.folder(stage, key)
        if folder.is_dir():
            self.hits.append(key)
            return folder
        return None

    def put(self, stage: str, key: str, files: Mapping[str, bytes]) -> Path:
        """Write `files` (name -> bytes) as the task's outputs, atomically."""
        final = self.folder(stage, key)
        final.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{key[:12]}.", suffix=".part", dir=final.parent))
        try:
            for name, data in files.items():
                (tmp / name).parent.mkdir(parents=True, exist_ok=True)
                (tmp / name).write_bytes(data)
            os.chmod(tmp, 0o755)
            if final.exists():       # another worker computed the same key: same content
                return final
            os.replace(tmp, final)
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
        return final

    def cached(self, stage: str, key: str, compute: Callable[[], Mapping[str, bytes]]) -> Path:
        """The task's folder, computing it in this process first when it is missing."""
        return self.get(stage, key) or self.put(stage, key, compute())


class Task(Protocol):
    """A unit of cached work: picklable (it travels to workers), its outputs plain bytes."""

    stage: ClassVar[str]
    version: ClassVar[int]

    def key(self) -> str:
        """`task_key(stage, version, config, inputs)` of what this task depends on."""

    def compute(self) -> Mapping[str, bytes]:
        """The outputs, file name -> bytes; raise `TaskFailed` for a failure the driver reports
        after the other tasks finish."""


class GroupedTask(Task, Protocol):
    """A task that can be computed together with others of its `group()` (same-shape models
    trained as one: `estimators.retlo.ensemble`). `compute_group(tasks)` returns each task's
    outputs, in order."""

    def group(self) -> Hashable:
        """Tasks with equal groups (and type) may be computed together."""

    @classmethod
    def compute_group(cls, tasks: list[Any]) -> list[Mapping[str, bytes]]: ...


class TaskFailed(Exception):
    """A task that could not produce its outputs (the physics left its valid regime)."""


class ShipsFiles:
    """A task whose input files travel with it, so that a Ray node (or a worker process) never
    reads the driver's files by path: pickled, each attribute named in `shipped` that holds a
    file's path carries the file's bytes instead, written on arrival into a folder of the
    receiving process's own and named there. Keys are taken on the driver, from the files."""

    shipped: ClassVar[tuple[str, ...]] = ()

    def __getstate__(self) -> dict[str, Any]:
        state = dict(self.__dict__)
        for name in self.shipped:
            value = state.get(name)
            if isinstance(value, str | os.PathLike) and Path(value).is_file():
                state[name] = _Shipped(Path(value).name, Path(value).read_bytes())
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        for name in self.shipped:
            value = state.get(name)
            if isinstance(value, _Shipped):
                folder = Path(tempfile.mkdtemp(prefix=f"{name}-", dir=_landing()))
                (folder / value.name).write_bytes(value.data)
                state[name] = folder / value.name
        self.__dict__.update(state)


@dataclass(frozen=True)
class _Shipped:
    name: str
    data: bytes


_landed: list[Path] = []


def _landing() -> Path:
    """This process's folder for shipped files, removed when it exits."""
    if not _landed:
        import atexit

        _landed.append(Path(tempfile.mkdtemp(prefix="macrostate-shipped-")))
        atexit.register(shutil.rmtree, _landed[0], True)
    return _landed[0]


@dataclass(frozen=True)
class Outcome:
    task: Any
    folder: Path | None       # None: failed
    failure: str | None = None
    cached: bool = False      # found in the cache (a resumed run's), not computed now


def _compute(task: Task) -> tuple[dict[str, bytes] | None, str | None]:
    try:
        return dict(task.compute()), None
    except TaskFailed as err:
        return None, str(err)


def _unit(items: list[tuple[int, Task]]) -> list[tuple[int, dict[str, bytes] | None,
                                                       str | None]]:
    """One unit of work: a task alone, or a group computed together (all fail together)."""
    if len(items) == 1:
        index, task = items[0]
        return [(index, *_compute(task))]
    tasks = [task for _, task in items]
    try:
        outputs = type(tasks[0]).compute_group(tasks)
    except TaskFailed as err:
        return [(index, None, str(err)) for index, _ in items]
    return [(index, dict(files), None) for (index, _), files in zip(items, outputs, strict=True)]


def _units(todo: list[tuple[int, Task]], group_size: int) -> list[list[tuple[int, Task]]]:
    """Tasks in units of work: with `group_size` > 1, tasks of one type and `group()` in
    chunks of that size, in task order; the rest alone. The chunks depend on the task list
    alone (never on workers or on what is cached), so a model's numbers do too."""
    if group_size <= 1:
        return [[item] for item in todo]
    groups: dict[Hashable, list[tuple[int, Task]]] = {}
    for i, task in todo:
        group = task.group() if hasattr(task, "group") else None
        groups.setdefault((type(task), group) if group is not None else (i,), []).append(
            (i, task))
    return [members[k:k + group_size] for members in groups.values()
            for k in range(0, len(members), group_size)]


def run_tasks(cache: TaskCache, tasks: Sequence[Task], workers: int = 1,
              ray: str | None = None, group_size: int = 1) -> Iterator[Outcome]:
    """Every task's outcome, cached ones first, the rest as workers finish them (in any
    order); a key shared by several tasks is computed once. With `group_size` > 1, tasks
    that share a `group()` (`GroupedTask`) are computed `group_size` at a time; a group is
    cached whole or not at all, so a resumed run computes the same groups as an uninterrupted
    one."""
    first: dict[str, tuple[int, Task]] = {}
    waiting: dict[str, list[Task]] = {}
    for i, task in enumerate(tasks):
        key = task.key()
        waiting.setdefault(key, []).append(task)
        first.setdefault(key, (i, task))
    keys = {i: k for k, (i, _) in first.items()}
    units = []
    for unit in _units(list(first.values()), group_size):
        folders = [cache.get(task.stage, keys[i]) for i, task in unit]
        if all(f is not None for f in folders):
            for (i, _), folder in zip(unit, folders, strict=True):
                for task in waiting[keys[i]]:
                    yield Outcome(task, folder, cached=True)
        else:
            units.append(unit)
    for results in runner_for(ray)(_unit, units, workers):
        for index, files, failure in results:
            key = keys[index]
            folder = None if files is None else cache.put(first[key][1].stage, key, files)
            for task in waiting[key]:
                yield Outcome(task, folder, failure)
