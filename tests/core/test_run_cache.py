"""The one run lifecycle and the one task cache: claims, statuses, keys by content, atomic
outputs, one computation per key whatever the worker count."""

import json
import pickle
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np
import pytest

from macrostate_mj.core.cache import ShipsFiles, TaskCache, TaskFailed, run_tasks, task_key
from macrostate_mj.core.errors import UserError
from macrostate_mj.core.run import Run, run_finished


def _manifest(out):
    return json.loads((out / "manifest.json").read_text())


def test_a_run_records_its_stages_and_how_it_ended(tmp_path):
    with Run(tmp_path, "demo", {"a": 1}, 7, ["result.txt"]) as run:
        assert _manifest(tmp_path)["status"] == "running"
        with run.stage("work"):
            (tmp_path / "result.txt").write_text("done")
        run.record(items=3)
    m = _manifest(tmp_path)
    assert m["status"] == "finished" and m["seed"] == 7 and m["items"] == 3
    assert set(m["timings_s"]) == {"work", "total"} and run_finished(tmp_path, {"a": 1})
    assert not run_finished(tmp_path, {"a": 2})


def test_a_manifest_says_which_code_made_it(tmp_path, monkeypatch):
    """The sources' digest changes with any source file; a checkout adds its commit."""
    import macrostate_mj.core.run as run_module

    with Run(tmp_path, "demo", {"a": 1}, 7, []):
        pass
    made = _manifest(tmp_path)["code"]
    assert len(made["digest"]) == 16 and made == run_module.code()
    assert made["commit"] is None or len(made["commit"]) == 40
    package = tmp_path / "pkg"
    (package / "macrostate_mj" / "core").mkdir(parents=True)
    (package / "macrostate_mj" / "a.py").write_text("x = 1\n")
    monkeypatch.setattr(run_module, "__file__", str(package / "macrostate_mj/core/run.py"))
    run_module.code.cache_clear()
    first = run_module.code()
    (package / "macrostate_mj" / "a.py").write_text("x = 2\n")
    run_module.code.cache_clear()
    second = run_module.code()
    run_module.code.cache_clear()
    assert first["digest"] != second["digest"] and first["commit"] is None   # no .git there


def test_a_finished_run_is_not_overwritten_without_asking(tmp_path):
    with Run(tmp_path, "demo", {"a": 1}, None):
        pass
    with pytest.raises(UserError, match="--overwrite"), Run(tmp_path, "demo", {"a": 1}, None):
        pass
    with Run(tmp_path, "demo", {"a": 2}, None, overwrite=True):
        pass
    assert _manifest(tmp_path)["config"] == {"a": 2}


def test_failed_and_interrupted_runs_say_so_and_resume_with_the_same_config_only(tmp_path):
    with pytest.raises(RuntimeError), Run(tmp_path, "demo", {"a": 1}, None):
        raise RuntimeError("the physics\nfailed")
    assert _manifest(tmp_path)["status"] == "failed"
    assert _manifest(tmp_path)["failure"] == "the physics failed"
    with pytest.raises(KeyboardInterrupt), Run(tmp_path, "demo", {"a": 1}, None):
        raise KeyboardInterrupt
    assert _manifest(tmp_path)["status"] == "interrupted"
    with pytest.raises(UserError, match="another config"), Run(tmp_path, "demo", {"a": 9}, None):
        pass
    with Run(tmp_path, "demo", {"a": 1}, None):       # the same config resumes
        pass
    assert _manifest(tmp_path)["status"] == "finished"


def test_bad_input_inside_a_run_leaves_nothing_behind(tmp_path):
    out = tmp_path / "new"
    with pytest.raises(UserError), Run(out, "demo", {}, None):
        raise UserError("bad value")
    assert not (out / "manifest.json").exists()


def test_products_of_an_unknown_run_are_not_clobbered(tmp_path):
    (tmp_path / "result.txt").write_text("someone's")
    with pytest.raises(UserError, match="result.txt already exists"), \
            Run(tmp_path, "demo", {}, None, ["result.txt"]):
        pass


def test_keys_follow_content_config_and_version(tmp_path):
    f = tmp_path / "data.csv"
    f.write_text("1,2")
    key = task_key("stage", 1, {"epochs": 20}, [f, np.arange(3)])
    assert key == task_key("stage", 1, {"epochs": 20}, [f, np.arange(3)])
    assert key != task_key("stage", 1, {"epochs": 200}, [f, np.arange(3)])
    assert key != task_key("stage", 2, {"epochs": 20}, [f, np.arange(3)])
    assert key != task_key("stage", 1, {"epochs": 20}, [f, np.arange(3.0)])
    f.write_text("1,3")
    assert key != task_key("stage", 1, {"epochs": 20}, [f, np.arange(3)])


@dataclass(frozen=True)
class Square:
    stage: ClassVar[str] = "square"
    version: ClassVar[int] = 1
    x: int

    def key(self) -> str:
        return task_key(self.stage, self.version, {"x": self.x})

    def compute(self) -> dict[str, bytes]:
        if self.x < 0:
            raise TaskFailed(f"{self.x} is negative")
        return {"y.json": json.dumps(self.x * self.x).encode()}


@pytest.mark.parametrize("workers", [1, 2])
def test_the_runner_computes_each_key_once_and_reports_failures(tmp_path, workers):
    cache = TaskCache(tmp_path)
    tasks = [Square(2), Square(3), Square(2), Square(-1)]
    got = {(o.task.x, None if o.folder is None else json.loads((o.folder / "y.json").read_text()),
            o.failure) for o in run_tasks(cache, tasks, workers)}
    assert got == {(2, 4, None), (3, 9, None), (-1, None, "-1 is negative")}
    assert sorted(p.name for p in (tmp_path / "square").iterdir()) == sorted(
        {Square(2).key(), Square(3).key()})          # no partial folder left
    again = list(run_tasks(cache, [Square(3)], workers))
    assert again[0].folder is not None and Square(3).key() in cache.hits


@dataclass(frozen=True)
class GroupedSquare(Square):
    """Squares that know their group (parity) and count the groups computed together."""

    def group(self) -> int:
        return self.x % 2

    @classmethod
    def compute_group(cls, tasks: list) -> list[dict[str, bytes]]:
        return [{"y.json": json.dumps(t.x * t.x).encode(),
                 "with.json": json.dumps(sorted(u.x for u in tasks)).encode()} for t in tasks]


@pytest.mark.parametrize("workers", [1, 2])
def test_grouped_tasks_are_computed_in_fixed_groups_and_cached_whole(tmp_path, workers):
    cache = TaskCache(tmp_path)
    tasks = [GroupedSquare(x) for x in (1, 2, 3, 4, 5, 6, 7)]
    out = {o.task.x: json.loads((o.folder / "with.json").read_text())
           if (o.folder / "with.json").exists() else [o.task.x]    # alone: plain `compute`
           for o in run_tasks(cache, tasks, workers, group_size=3)}
    # by group (odd, even), in task order, 3 at a time: whatever the workers
    assert out == {1: [1, 3, 5], 3: [1, 3, 5], 5: [1, 3, 5], 7: [7],
                   2: [2, 4, 6], 4: [2, 4, 6], 6: [2, 4, 6]}
    assert len(list(run_tasks(cache, tasks, workers, group_size=3))) == 7
    assert len(cache.hits) == 7                    # a rerun computes nothing


class _Reads(ShipsFiles):
    stage: ClassVar[str] = "reads"
    version: ClassVar[int] = 1
    shipped: ClassVar[tuple[str, ...]] = ("data", "absent")

    def __init__(self, data: Path, absent: Path, kept: Path):
        self.data, self.absent, self.kept = data, absent, kept

    def key(self) -> str:
        return task_key(self.stage, self.version, {}, [self.data])

    def compute(self) -> dict[str, bytes]:
        return {"out": self.data.read_bytes()[::-1]}


def test_a_task_ships_its_input_files_so_no_node_reads_the_drivers_by_path(tmp_path):
    data = tmp_path / "Train.csv"
    data.write_bytes(b"1,2,3\n")
    task = _Reads(data, tmp_path / "never.csv", tmp_path / "kept.csv")
    key = task.key()
    wire = pickle.dumps(task)
    data.unlink()                                  # the driver's file is not on the node
    landed = pickle.loads(wire)
    assert landed.data.name == "Train.csv" and landed.data.parent != tmp_path
    assert landed.compute() == {"out": b"\n3,2,1"} and landed.key() == key
    assert landed.absent == tmp_path / "never.csv"          # no file there: a path as it was
    assert landed.kept == tmp_path / "kept.csv"             # not shipped: a path as it was
