"""The docs: tutorial code runs as written, the site builds without a warning, and every number on
a results page comes from a committed results file or from the dissertation's values."""

import functools
import json
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest
from conftest import REPO

DOCS = REPO / "docs"
RESULTS = REPO / "results"
# Pages whose code a reader copies: every ```python block runs, in order, in one scope a page.
TUTORIALS = [REPO / "README.md", DOCS / "getting-started.md",
             *sorted((DOCS / "tutorials").glob("*.md"))]
# Pages that report measurements: none may show a number that no results file holds.
RESULTS_PAGES = ["reproduction/chapter2", "reproduction/chapter3", "reproduction/chapter4",
                 "reproduction/beyond", "benchmarks"]
NUMBER = re.compile(r"(?<![\w.])[-−]?(?:\d+(?:,\d{3})+|\d*\.\d+|\d+)(?:e[-+]?\d+)?(?![\w])")


def _blocks(page: Path) -> list[str]:
    return re.findall(r"^```python\n(.*?)^```", page.read_text(), re.S | re.M)


@pytest.mark.parametrize("page", [p for p in TUTORIALS if _blocks(p)], ids=lambda p: p.stem.lower())
def test_tutorial_code_runs_as_written(page: Path, tmp_path, monkeypatch):
    monkeypatch.chdir(REPO)             # tutorials name files of the repository (examples/)
    scope: dict = {}
    for i, block in enumerate(_blocks(page)):
        exec(compile(block, f"{page.relative_to(REPO)}:block{i}", "exec"), scope)
    if page.stem == "getting-started":  # what its comments promise
        sim, seen, frame = scope["sim"], scope["seen"], scope["frame"]
        assert abs(sim.time - 10.0) < 1e-9 and sim.poses.shape == (5, 3)
        assert frame.shape == (570, 750, 3) and frame.dtype == np.uint8
        assert seen.detected.all()
        assert np.abs(seen.poses[:, :2] - sim.poses[:, :2]).max() < 0.005


@pytest.fixture(scope="module")
def text_build(tmp_path_factory) -> Path:
    """The site built as plain text, warnings as errors (what `make docs` does for HTML)."""
    out = tmp_path_factory.mktemp("docs")
    run = subprocess.run([sys.executable, "-m", "sphinx", "-b", "text", "-W", "--keep-going",
                          "-q", str(DOCS), str(out)], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr[-3000:]
    return out


@functools.cache
def _allowed() -> frozenset[str]:
    """Every number the results files hold, as written and rounded to 0-4 decimals (also as a
    percentage, and in cm for values in m), and every number of the dissertation's claims."""
    texts = [p.read_text() for p in RESULTS.rglob("*") if p.suffix in (".json", ".jsonl", ".toml",
                                                                       ".md")]
    texts.append((DOCS / "reproduction" / "claims.toml").read_text())
    allowed: set[str] = set()
    for text in texts:
        for token in re.findall(r"-?\d+(?:\.\d+)?(?:e-?\d+)?", text):
            allowed.add(token.lstrip("-"))
            value = abs(float(token))
            for v in (value, value * 100):
                for digits in range(5):
                    allowed.add(f"{v:.{digits}f}")
                allowed |= {f"{v:.2g}", f"{v:.3g}"}
    allowed |= {f"{s}".lstrip("0") for s in list(allowed) if s.startswith("0.")}
    return frozenset(allowed)


def test_the_site_builds_without_a_warning(text_build):
    assert (text_build / "index.txt").is_file()


@pytest.mark.parametrize("page", RESULTS_PAGES)
def test_results_pages_show_only_numbers_the_results_files_hold(text_build, page):
    allowed = _allowed()
    text = (text_build / f"{page}.txt").read_text()
    # Figure, table and section labels name the dissertation, they are not measurements; dates
    # are the manifests' (`created_unix`, shown as a date).
    text = re.sub(r"\d{4}-\d{2}-\d{2}", " ", text)
    text = re.sub(r"(Fig|Table|§|Chapter|chapter|Figure|m =|σ =|[Ss]plit|seed|D[+-])\s*[\d.]+",
                  " ", text)
    unknown = sorted({n for n in NUMBER.findall(text)
                      if n.replace(",", "").lstrip("-−") not in allowed})
    assert not unknown, f"{page}: numbers no results file holds: {unknown}"


def test_the_readme_is_short_and_points_to_the_docs():
    readme = (REPO / "README.md").read_text()
    assert len(readme.splitlines()) <= 200
    assert "docs/" in readme


def test_every_results_folder_is_indexed():
    index = tomllib.loads((RESULTS / "index.toml").read_text())
    folders = {p.name for p in RESULTS.iterdir() if p.is_dir()}
    assert folders <= set(index), f"not in results/index.toml: {sorted(folders - set(index))}"
    for name, entry in index.items():
        assert {"kind", "command"} <= set(entry), name
        assert entry["kind"].startswith(("result", "smoke")), name


def test_committed_bench_lines_have_the_common_schema():
    for path in RESULTS.rglob("bench*.jsonl"):
        for line in path.read_text().splitlines():
            row = json.loads(line)
            assert {"suite", "name", "value", "unit", "limit", "ratio", "config"} <= set(row)


def test_the_reference_speaks_of_the_software_not_of_its_history():
    """History lives in CHANGELOG.md and docs/decisions/; elsewhere no page speaks of issues,
    sessions or stops."""
    pages = [p for p in DOCS.rglob("*.md")
             if "decisions" not in p.parts and "_build" not in p.parts]
    pages.append(REPO / "README.md")
    for page in pages:
        words = re.findall(r"\b(issue|session|previous stop|last stop)s?\b", page.read_text(), re.I)
        assert not words, f"{page.relative_to(REPO)}: {sorted(set(words))}"
