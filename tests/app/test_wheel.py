"""The package installs and runs like any other: a wheel built from the checkout carries its
robots and scenes, and its installed copy, not the checkout, simulates from any folder.

The venv holds an editable install of the checkout: a meta-path finder (`__editable___*_finder`)
that setuptools appends to `sys.meta_path`, after the ordinary path finder. So a target folder on
`PYTHONPATH` wins for every top-level package, and `python -v` (which logs each module file it
loads) shows whether any module still came from the checkout.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest
from conftest import REPO

PACKAGES = ("macrostate_mj", "collectors", "estimators", "viz")
ASSETS = REPO / "macrostate_mj" / "assets" / "mjcf"


def _pip(*args: str) -> None:
    subprocess.run([sys.executable, "-m", "pip", "--disable-pip-version-check", "-q", *args],
                   check=True, capture_output=True, text=True, timeout=300)


@pytest.fixture(scope="module")
def installed(tmp_path_factory) -> tuple[Path, Path]:
    """(the wheel, the folder it is installed into). Built from a copy of the checkout's sources:
    an in-tree build would leave build/ and *.egg-info in the shared working tree, and a stale
    build/lib could carry deleted modules into the wheel."""
    tmp = tmp_path_factory.mktemp("wheel")
    src = tmp / "src"
    src.mkdir()
    shutil.copy2(REPO / "pyproject.toml", src)
    for pkg in PACKAGES:
        shutil.copytree(REPO / pkg, src / pkg, ignore=shutil.ignore_patterns("__pycache__"))
    _pip("wheel", str(src), "--no-deps", "--no-build-isolation", "--no-index",
         "-w", str(tmp / "dist"))
    (wheel,) = (tmp / "dist").glob("macrostate_mj-*.whl")
    _pip("install", "--no-deps", "--no-index", "--target", str(tmp / "site"), str(wheel))
    return wheel, tmp / "site"


def _installed_env(site: Path) -> dict[str, str]:
    """The user's environment, with the installed copy first on the path and no reference data
    configured (the installed default is under test)."""
    env = {k: v for k, v in os.environ.items() if k != "MACROSTATE_REFERENCE_DATA"}
    return {**env, "PYTHONPATH": str(site), "MUJOCO_GL": env.get("MUJOCO_GL", "egl")}


def test_the_wheel_carries_every_asset_and_only_the_packages(installed):
    wheel, _ = installed
    names = set(zipfile.ZipFile(wheel).namelist())
    assets = {p.relative_to(REPO).as_posix() for p in ASSETS.rglob("*")
              if p.is_file() and "__pycache__" not in p.parts}
    assert any(a.endswith(".xml") for a in assets)
    assert assets - names == set(), "assets left out of the wheel (pyproject package-data)"
    assert "macrostate_mj/py.typed" in names and "macrostate_mj/__main__.py" in names
    tops = {n.split("/", 1)[0] for n in names}
    assert tops == {*PACKAGES, "macrostate_mj-0.1.0.dist-info"}, tops


def test_the_installed_copy_simulates_from_outside_the_checkout(installed, tmp_path):
    _, site = installed
    env, cwd = _installed_env(site), tmp_path / "elsewhere"
    env["MACROSTATE_DATA_CACHE"] = str(tmp_path / "cache")
    cwd.mkdir()
    probe = subprocess.run(
        [sys.executable, "-c", "import json, collectors, estimators, viz, macrostate_mj\n"
         "from macrostate_mj.core import paths\n"
         "print(json.dumps({'files': [m.__file__ for m in (macrostate_mj, collectors, "
         "estimators, viz)], 'assets': str(paths.ASSETS), 'checkout': paths.CHECKOUT, "
         "'reference': str(paths.reference_data())}))"],
        cwd=cwd, env=env, capture_output=True, text=True, timeout=60)
    assert probe.returncode == 0, probe.stderr
    seen = json.loads(probe.stdout)
    for file in seen["files"]:
        assert Path(file).is_relative_to(site), file
    assert Path(seen["assets"]).is_relative_to(site) and seen["checkout"] is None
    assert seen["reference"] == str(tmp_path / "cache")   # the fetch cache, not site-packages

    out = tmp_path / "out"
    run = subprocess.run([sys.executable, "-v", "-m", "macrostate_mj", "simulate", "--robots",
                          "3", "--seconds", "2", "--out", str(out)],
                         cwd=cwd, env=env, capture_output=True, text=True, timeout=120)
    log = run.stderr.splitlines()
    assert run.returncode == 0, "\n".join(ln for ln in log if not ln.startswith(("#", "import ")))
    from_checkout = [ln for ln in log for pkg in PACKAGES if str(REPO / pkg) + os.sep in ln]
    assert from_checkout == [], from_checkout[:5]
    assert any(str(site / "macrostate_mj" / "chain" / "world.py") in ln for ln in log)
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["status"] == "finished" and manifest["simulated_seconds"] == pytest.approx(2.0)
    assert (out / "poses.parquet").stat().st_size > 0
    # an installed copy has no commit of its own: only the digest of its sources
    assert manifest["code"]["commit"] is None and len(manifest["code"]["digest"]) == 16


def test_the_installed_copy_judges_a_checkouts_claims(installed, tmp_path):
    """The claims ship in the wheel: judged on a checkout's results from anywhere."""
    _, site = installed
    run = subprocess.run([sys.executable, "-m", "macrostate_mj", "claims", "--results",
                          str(REPO / "results"), "--chapter", "chapter4", "--json"],
                         cwd=tmp_path, env=_installed_env(site), capture_output=True, text=True,
                         timeout=120)
    assert run.returncode == 0, run.stderr
    rows = [json.loads(line) for line in run.stdout.splitlines()]
    assert len(rows) == 13 and {r["chapter"] for r in rows} == {"chapter4"}
