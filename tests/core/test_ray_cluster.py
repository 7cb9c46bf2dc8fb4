"""`--ray HOST:PORT` on a real cluster: a head and a second node, each its own `ray start --block`
process on this machine, run `collect` and an experiment as two machines would. Their outputs
are byte for byte those of local workers, and Ray's task records show both nodes at work; a
driver without the cluster's token, or a node without the package, is one line.

The cluster is this module's own (free ports, its own temporary folders and token), so other
files' Ray runs never meet it (`--ray local` starts an instance of its own). It is stopped by
the ids of the processes started here, never with `ray stop`, which stops every Ray on the
machine."""

from __future__ import annotations

import json
import os
import secrets
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

import pytest
from clitools import assert_clean_error

ray = pytest.importorskip("ray")
psutil = pytest.importorskip("psutil")

RAY = Path(sys.executable).with_name("ray")
TINY = ["--robots", "3", "--minutes", "0.75", "--episode-minutes", "0.25", "--seed", "5",
        "--split", "60/10/30"]
TIMED = {"manifest.json", "stats.json", "timing.json"}      # hold wall times: not compared
TOKEN = secrets.token_hex(32)

# Run in a fresh interpreter joined to the cluster: its live nodes and, for the driver whose
# command line holds `marker`, the node of each task it ran (`_unit`: cache.run_tasks' work);
# it waits up to a minute for two nodes and `want` tasks (workers report tasks a moment late).
# The records are read from the head itself: the state API would need Ray's dashboard.
RECORDS = r"""
import json, logging, sys, time
import ray
from ray._private.state import state

address, marker, want = sys.argv[1], sys.argv[2], int(sys.argv[3])
ray.init(address=address, log_to_driver=False, logging_level=logging.ERROR)
deadline = time.time() + 60
while True:
    nodes = sorted(n["NodeID"] for n in ray.nodes() if n["Alive"])
    jobs = {j["JobID"] for j in state.job_table()
            if marker and marker in j.get("Entrypoint", "")}
    ran = [e.state_updates.node_id.hex() for e in state._get_all_task_events()
           if e.job_id.hex() in jobs and e.task_info.name == "_unit"
           and e.state_updates.node_id]
    if len(nodes) >= 2 and len(ran) >= want or time.time() > deadline:
        break
    time.sleep(0.5)
print(json.dumps({"nodes": nodes, "ran": ran}))
"""

# A node without the package: on its workers, importing it fails as on a machine without it.
LACKING = """
import sys


class Lacking:
    @staticmethod
    def find_spec(name, path=None, target=None):
        if name.split(".")[0] in ("macrostate_mj", "collectors", "estimators", "viz"):
            raise ModuleNotFoundError(f"No module named {name!r}", name=name)
        return None


sys.meta_path.insert(0, Lacking)
"""


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("", 0))
        return s.getsockname()[1]


def _env(**extra: str) -> dict[str, str]:
    """This process's environment without any Ray setting of the user's (no RAY_ADDRESS to
    follow), with the cluster's token."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("RAY_")}
    return {**env, "RAY_AUTH_MODE": "token", "RAY_AUTH_TOKEN": TOKEN,
            "RAY_USAGE_STATS_ENABLED": "0", **extra}


class Cluster:
    """`ray start --block` processes on 127.0.0.1, each with its own temporary folder (short:
    Ray's sockets live under it) and ports, stopped by their ids."""

    def __init__(self) -> None:
        self.port = _free_port()
        self.address = f"127.0.0.1:{self.port}"
        self.procs: list[subprocess.Popen] = []
        self.folders: list[Path] = []

    def start(self, head: bool, **env: str) -> None:
        folder = Path(tempfile.mkdtemp(prefix="mmj-ray-",
                                       dir="/tmp" if os.path.isdir("/tmp") else None))
        self.folders.append(folder)
        args = [str(RAY), "start", "--block", "--node-ip-address", "127.0.0.1",
                "--num-cpus", "1", "--temp-dir", str(folder), "--disable-usage-stats",
                "--dashboard-agent-listen-port", str(_free_port())]
        args += (["--head", "--port", str(self.port), "--include-dashboard", "false",
                  "--dashboard-port", str(_free_port())] if head else
                 ["--address", self.address])
        with open(folder / "start.log", "wb") as log:
            self.procs.append(subprocess.Popen(args, env=_env(**env), stdout=log,
                                               stderr=subprocess.STDOUT))

    def wait_for_head(self) -> None:
        deadline = time.time() + 90
        while time.time() < deadline:
            self._alive()
            try:
                socket.create_connection(("127.0.0.1", self.port), timeout=1).close()
                return
            except OSError:
                time.sleep(0.5)
        pytest.fail(f"the Ray head did not listen on {self.address}: {self._logs()}")

    def records(self, marker: str = "", want: int = 0) -> dict:
        self._alive()
        res = subprocess.run([sys.executable, "-c", RECORDS, self.address, marker, str(want)],
                             env=_env(), capture_output=True, text=True, timeout=120)
        assert res.returncode == 0, res.stderr[-3000:]
        return json.loads(res.stdout.strip().splitlines()[-1])

    def stop(self) -> list[str]:
        """SIGTERM to each `ray start --block` (the joined node first), which stops what it
        started; its processes still there after that are named and killed."""
        left = []
        for proc in reversed(self.procs):
            try:
                family = psutil.Process(proc.pid).children(recursive=True)
            except psutil.NoSuchProcess:
                family = []
            proc.terminate()
            try:
                proc.wait(60)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
                left.append(f"{proc.pid} ray start")
            for p in psutil.wait_procs(family, timeout=30)[1]:
                try:
                    left.append(f"{p.pid} {p.name()}")
                    p.kill()
                except psutil.NoSuchProcess:
                    pass
        for folder in self.folders:
            shutil.rmtree(folder, ignore_errors=True)
        return left

    def _alive(self) -> None:
        if any(p.poll() is not None for p in self.procs):
            pytest.fail(f"a `ray start` process ended: {self._logs()}")

    def _logs(self) -> str:
        return " | ".join((f / "start.log").read_text(errors="replace")[-1500:]
                          for f in self.folders if (f / "start.log").exists())


@pytest.fixture(scope="module")
def cluster():
    c = Cluster()
    try:
        c.start(head=True)
        c.wait_for_head()
        c.start(head=False)
        assert len(c.records()["nodes"]) == 2, c._logs()
        yield c
    finally:
        left = c.stop()
    assert not left, f"left running: {left}"


def _cli(*args: str, cwd: Path, **env: str) -> subprocess.CompletedProcess:
    """The command in a fresh interpreter, outside the repository (a task must not find the
    package by the driver's folder)."""
    return subprocess.run([sys.executable, "-m", "macrostate_mj.app.cli", *args],
                          env=_env(**env), cwd=cwd, capture_output=True, text=True,
                          timeout=300)


def _files(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file() and p.name not in TIMED}


def _on_ray_and_local(cluster: Cluster, tmp_path: Path, args: list[str], tasks: int
                      ) -> tuple[dict, dict, Counter, list]:
    """The command's outputs on the cluster and on two local workers, the tasks each node ran
    (from Ray's records) and the cluster's nodes."""
    on_ray, local = tmp_path / "ray", tmp_path / "local"
    res = _cli(*args, "--ray", cluster.address, "--out", str(on_ray), cwd=tmp_path)
    assert res.returncode == 0, res.stderr[-3000:]
    res = _cli(*args, "--workers", "2", "--out", str(local), cwd=tmp_path)
    assert res.returncode == 0, res.stderr[-3000:]
    seen = cluster.records(str(on_ray), tasks)
    ran = Counter(seen["ran"])
    print(f"{' '.join(args[:2])}: tasks per node {dict(ran)}")
    return _files(on_ray), _files(local), ran, seen["nodes"]


@pytest.mark.slow
def test_collect_on_two_nodes_is_byte_identical_to_local_workers(cluster, tmp_path):
    ours, theirs, ran, nodes = _on_ray_and_local(cluster, tmp_path, ["collect", *TINY], tasks=3)
    assert sorted(ours) == sorted(theirs)
    assert [name for name in ours if ours[name] != theirs[name]] == []
    assert sum(ran.values()) == 3 and set(ran) == set(nodes), (ran, nodes)


@pytest.fixture(scope="module")
def lab(tmp_path_factory) -> Path:
    """A small lab collection (local workers) to train on: no real data needed."""
    out = tmp_path_factory.mktemp("lab") / "lab"
    res = _cli("collect", "--robots", "3", "--minutes", "2.5", "--episode-minutes", "1.25",
               "--seed", "6", "--split", "80/20/0", "--workers", "2", "--out", str(out),
               cwd=out.parent)
    assert res.returncode == 0, res.stderr[-3000:]
    return out


@pytest.mark.slow
def test_an_experiment_on_two_nodes_is_byte_identical_to_local_workers(cluster, tmp_path, lab):
    """`experiment retlo`'s quick profile on a lab collection: its two models (arrays in,
    checkpoints out) train on the two nodes."""
    ours, theirs, ran, nodes = _on_ray_and_local(cluster, tmp_path, [
        "experiment", "retlo", "--profile", "quick", "--train", str(lab / "Train.csv"),
        "--val", str(lab / "Val.csv")], tasks=2)
    assert sorted(ours) == sorted(theirs)
    assert [name for name in ours if ours[name] != theirs[name]] == []
    assert sum(ran.values()) == 2 and set(ran) == set(nodes), (ran, nodes)


@pytest.mark.slow
def test_a_driver_without_the_clusters_token_is_one_line(cluster, tmp_path):
    out = tmp_path / "never"
    t0 = time.time()
    res = _cli("collect", *TINY, "--ray", cluster.address, "--out", str(out), cwd=tmp_path,
               RAY_AUTH_MODE="disabled", RAY_AUTH_TOKEN="")
    assert_clean_error(res, cluster.address, "RAY_AUTH_MODE=token")
    assert time.time() - t0 < 60 and not out.exists()


@pytest.mark.slow
def test_a_node_without_the_package_is_one_line(tmp_path):
    shadow = tmp_path / "lacking"
    shadow.mkdir()
    (shadow / "sitecustomize.py").write_text(LACKING)
    lone = Cluster()
    try:
        lone.start(head=True, PYTHONPATH=os.pathsep.join(
            [str(shadow), *filter(None, [os.environ.get("PYTHONPATH")])]))
        lone.wait_for_head()
        res = _cli("collect", *TINY, "--ray", lone.address, "--out", str(tmp_path / "out"),
                   cwd=tmp_path)
    finally:
        left = lone.stop()
    assert not left, f"left running: {left}"
    assert_clean_error(res, lone.address, "cannot import", "pip install 'macrostate-mj[ray]'")


def test_ray_local_starts_an_instance_of_its_own(monkeypatch):
    """`--ray local` never joins a cluster already running on the machine (what `ray.init()`
    with no address does, following ray_current_cluster or RAY_ADDRESS)."""
    from macrostate_mj.core.parallel import ray_runner

    seen = {}
    monkeypatch.setattr(ray, "init", lambda **kw: seen.update(kw))
    ray_runner("local")
    assert seen["address"] == "local"
