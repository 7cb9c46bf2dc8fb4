"""One run lifecycle: claim the output folder, time each stage, and record in one manifest how the
run ended.

Every command and experiment writes its outputs through a `Run`:

    with Run(out, "experiment caging", config, seed, PRODUCTS, overwrite) as run:
        with run.stage("train"):
            ...
        run.record(models_trained=3)

The manifest (`manifest.json`) says what ran (command line, config and its hash, seed, code and
library versions, machine), per-stage timings, and a `status`: `running` while the run works,
then `finished`, `failed` (with the one-line reason) or `interrupted`. A folder whose run did
not finish may be resumed by the same command with the same config (its cached tasks are kept);
another config there is refused, as is a finished run without `--overwrite`. Bad input found
inside the run (a `UserError`) leaves the manifest as it was: nothing half-written.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import json
import os
import platform
import sys
import time
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

from macrostate_mj import __version__
from macrostate_mj.core.errors import UserError
from macrostate_mj.core.io import (
    check_writable_dir,
    jsonable,
    write_json_atomic,
    write_text_atomic,
)

MANIFEST = "manifest.json"
RUNNING, FINISHED, FAILED, INTERRUPTED = "running", "finished", "failed", "interrupted"


def config_hash(config: Any) -> str:
    """sha256 of the config's canonical JSON: what a run (or a cached task) was made from."""
    text = json.dumps(jsonable(config), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


class Run:
    """A command's run in its output folder (see the module docstring)."""

    def __init__(self, out: str | os.PathLike, command: str, config: Any, seed: int | None,
                 products: Sequence[str] = (), overwrite: bool = False,
                 manifest: str = MANIFEST):
        self.out, self.command, self.config, self.seed = Path(out), command, config, seed
        self.products, self.overwrite = list(products), overwrite
        self.path = self.out / manifest
        self.config_hash = config_hash(config)
        self.timings: dict[str, float] = {}
        self.extra: dict[str, Any] = {}
        self._previous: str | None = None
        self._t0 = 0.0

    # --- lifecycle ---
    def __enter__(self) -> Run:
        self.claim()
        self._t0 = time.perf_counter()
        self._write(RUNNING)
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 _tb: object) -> None:
        self.timings.setdefault("total", time.perf_counter() - self._t0)
        if exc_type is None:
            self._write(FINISHED)
        elif issubclass(exc_type, UserError):      # bad input: leave the folder as it was
            self._restore()
        elif issubclass(exc_type, KeyboardInterrupt):
            self._write(INTERRUPTED)
        else:
            self._write(FAILED, failure=" ".join(str(exc).split())[:500] or exc_type.__name__)

    def claim(self) -> None:
        """Check the folder before any work: refuse a file, a finished run or another run's
        unfinished outputs unless --overwrite; keep an unfinished run of this config."""
        if self.out.exists() and not self.out.is_dir():
            raise UserError(f"--out {self.out} is a file, not a folder; choose a folder path")
        check_writable_dir(self.out, create=False)
        previous = _read(self.path)
        self._previous = self.path.read_text() if previous is not None else None
        if self.overwrite:
            return
        status = None if previous is None else previous.get("status", FINISHED)
        if status == FINISHED:
            raise UserError(f"{self.path} already exists; pass --overwrite or choose another "
                            "--out")
        if status is None:
            existing = [p for p in self.products if (self.out / p).exists()]
            if existing:
                raise UserError(f"{self.out / existing[0]} already exists; pass --overwrite or "
                                "choose another --out")
        elif previous.get("config_hash") != self.config_hash:
            raise UserError(f"{self.out} holds an unfinished `{previous.get('command')}` run "
                            "with another config; pass --overwrite or choose another --out")

    @contextlib.contextmanager
    def stage(self, name: str) -> Iterator[None]:
        """Time a stage (seconds add up when a stage is entered more than once)."""
        t0 = time.perf_counter()
        try:
            yield
        finally:
            self.timings[name] = self.timings.get(name, 0.0) + time.perf_counter() - t0

    def record(self, **extra: Any) -> None:
        """Add fields to the manifest (counts, output paths, what was resumed)."""
        self.extra.update(extra)

    # --- the manifest ---
    def _write(self, status: str, **more: Any) -> None:
        self.out.mkdir(parents=True, exist_ok=True)
        write_json_atomic(self.path, {
            "command": self.command,
            "argv": sys.argv[1:],
            "status": status,
            "config": self.config,
            "config_hash": self.config_hash,
            "seed": self.seed,
            "version": __version__,
            "code": code(),
            "versions": {"python": platform.python_version(),   # numeric libraries loaded
                         **{lib: sys.modules[lib].__version__
                            for lib in ("mujoco", "numpy", "torch") if lib in sys.modules}},
            "machine": machine(),
            "created_unix": round(time.time(), 3),
            "timings_s": {k: round(v, 4) for k, v in self.timings.items()},
            **self.extra, **more,
        })

    def _restore(self) -> None:
        if self._previous is None:
            self.path.unlink(missing_ok=True)
        else:
            write_text_atomic(self.path, self._previous)


@functools.cache
def code() -> dict[str, Any]:
    """Which code made a run: a digest of the installed packages' sources (the same files give
    the same digest, in a checkout or a wheel) and, in a git checkout, its commit and whether
    the tree had uncommitted changes. A folder's numbers say beside them if other code made them."""
    import subprocess

    root = Path(__file__).resolve().parents[2]
    digest = hashlib.sha256()
    for package in PACKAGES:
        for file in sorted((root / package).rglob("*")):
            if file.suffix in (".py", ".toml", ".xml") and "__pycache__" not in file.parts:
                digest.update(f"{file.relative_to(root)}\n".encode() + file.read_bytes())
    out: dict[str, Any] = {"digest": digest.hexdigest()[:16], "commit": None, "dirty": None}
    with contextlib.suppress(OSError, subprocess.SubprocessError):
        if not (root / ".git").exists():          # a wheel: never an enclosing repository's
            return out
        git = ["git", "-C", str(root)]
        head = subprocess.run([*git, "rev-parse", "HEAD"], capture_output=True, text=True,
                              timeout=10)
        if head.returncode == 0:
            status = subprocess.run([*git, "status", "--porcelain", "--", *PACKAGES],
                                    capture_output=True, text=True, timeout=10)
            out.update(commit=head.stdout.strip(), dirty=bool(status.stdout.strip()))
    return out


PACKAGES = ("macrostate_mj", "collectors", "estimators", "viz")   # what a run's code is


def machine() -> dict[str, Any]:
    """Where a run ran (float results repeat bit for bit only on the same CPU type)."""
    cpu = platform.processor() or "unknown"
    with contextlib.suppress(OSError):
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    return {"cpu": cpu, "arch": platform.machine(), "cores": os.cpu_count()}


def _read(path: Path) -> dict | None:
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


def run_finished(out: Path, config: Any, manifest: str = MANIFEST) -> bool:
    """Has a run of exactly this config finished in `out`? (A stage of a larger experiment
    reuses it instead of running it again.)"""
    previous = _read(Path(out) / manifest)
    return (previous is not None and previous.get("status", FINISHED) == FINISHED
            and previous.get("config_hash") == config_hash(config))
