"""The docs: tutorial code runs as written, the site builds without a warning, and every number on
a results page comes from a committed results file or from the dissertation's values."""

import json
import re
import shlex
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import REPO

from macrostate_mj.app.results.claims import load_claims
from macrostate_mj.app.results.provenance import DISCLOSED, is_result, read_index

DOCS = REPO / "docs"
RESULTS = REPO / "results"
# Pages whose code a reader copies: every ```python block runs, in order, in one scope a page.
TUTORIALS = [REPO / "README.md", DOCS / "getting-started.md",
             *sorted((DOCS / "tutorials").glob("*.md"))]
# Pages that report measurements: none may show a number that no results file holds.
RESULTS_PAGES = ["reproduction/chapter2", "reproduction/chapter3", "reproduction/chapter4",
                 "reproduction/beyond", "reproduction/sim-to-real", "benchmarks"]
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


# Numbers a results page types in its prose: settings of the protocol and counts, never a
# measurement (a measured number is a source's: `{n}`, a table, the claims). Adding one here is a
# reviewed act; each must still be typed on its page.
TYPED = {
    "reproduction/chapter2": {"0", "1,600", "15", "150", "2", "3", "4", "5", "6"},
    "reproduction/chapter3": {"150", "2", "26", "3", "300", "5", "6"},
    "reproduction/chapter4": {".05", "160", "20", "20,000", "3", "4.13", "40", "48", "5", "750",
                              "95"},
    "reproduction/beyond": {"0", "1", "1000", "19", "2", "2.5", "2023", "245,760", "3", "5",
                            "50", "90"},
    "reproduction/sim-to-real": {"0.02", "0.3", "1", "15", "2", "26", "3", "30", "300", "95"},
    "benchmarks": {"1", "1.0", "1024", "45"},
}
LABELS = re.compile(r"(Fig|Table|§|Chapter|chapter|Figure|m =|σ =|[Ss]plit|seed|D[+-])\s*[\d.]+")


def _numbers(text: str) -> set[str]:
    """The numbers a text shows, labels (figure, table, split, seed) and dates left out."""
    text = LABELS.sub(" ", re.sub(r"\d{4}-\d{2}-\d{2}", " ", text))
    return {n.replace("−", "-").lstrip("-") for n in NUMBER.findall(text)}


def _prose(page: str) -> str:
    """A page's markdown as typed: roles, directives, code and images left out."""
    text = (DOCS / f"{page}.md").read_text()
    for pattern in (r"\{n\}`[^`]*`", r"```\{[^`]*?```", r"`[^`]*`", r"!\[[^\]]*\]\([^)]*\)"):
        text = re.sub(pattern, " ", text, flags=re.S)
    return text


def _given(text_build: Path, page: str) -> list:
    """What each source gave the page when it was built: [expression, text or table rows]."""
    return json.loads((text_build / "_numbers.json").read_text()).get(page, [])


def test_the_site_builds_without_a_warning(text_build):
    assert (text_build / "index.txt").is_file()


@pytest.mark.parametrize("page", RESULTS_PAGES)
def test_results_pages_show_only_numbers_their_sources_gave_them(text_build, page):
    """Every number a results page shows was given to that page by a named source (or is one
    of its few typed settings): a number typed into the prose, or left behind when its source
    changed, fails here."""
    given: set[str] = set()
    for _, shown in _given(text_build, page):
        cells = [c for row in shown for c in row] if isinstance(shown, list) else [shown]
        for cell in cells:               # labels kept: a table may wrap one apart
            given |= {n.replace("−", "-").lstrip("-") for n in NUMBER.findall(str(cell))}
    typed = _numbers(_prose(page))
    assert TYPED[page] == typed, f"{page}: typed numbers changed: {sorted(typed ^ TYPED[page])}"
    shown_numbers = _numbers((text_build / f"{page}.txt").read_text())
    unknown = sorted(n for n in shown_numbers if n not in given | TYPED[page])
    assert not unknown, f"{page}: numbers no source gave: {unknown}"


def _reread(expression: str) -> str:
    """An inline number read again by this test from its file, key and rounding."""
    name, args = re.fullmatch(r"(\w+)\((.*)\)", expression, re.S).groups()
    path, key, *rest = [a.strip() for a in args.split(",")]
    data = json.loads((RESULTS / path).read_text()) if path.endswith(".json") else [
        json.loads(line) for line in (RESULTS / path).read_text().splitlines() if line.strip()]
    for part in filter(None, key.split("/")):
        data = data[int(part)] if isinstance(data, list) else data[part]
    if name == "json":
        fmt, unit, scale = (rest + [".2f", "", "1"][len(rest):])[:3]
        value = format(float(data) * float(scale), fmt)
        return value + (f" {unit}" if unit else "")
    fmt, unit = (rest + [".3f", ""][len(rest):])[:2]
    text = format(float(data["mean"]), fmt) + " ± " + format(float(data["std"]), fmt)
    return text + (f" {unit}" if unit else "")


@pytest.mark.parametrize("page", RESULTS_PAGES)
def test_every_inline_number_is_its_file_key_and_rounding(text_build, page):
    """Each `{n}` of a plain file and key (json, meanstd) shows exactly what this test reads
    there at the role's rounding, and the built page shows that text."""
    built = " ".join((text_build / f"{page}.txt").read_text().split())
    checked = 0
    for expression, shown in _given(text_build, page):
        if re.match(r"(json|meanstd)\(", expression):
            assert shown == _reread(expression), expression
            assert " ".join(shown.split()) in built, expression
            checked += 1
    assert checked or page == "benchmarks", f"{page}: no inline number was checked"


def test_the_readme_is_short_and_points_to_the_docs():
    readme = (REPO / "README.md").read_text()
    assert len(readme.splitlines()) <= 200
    assert "docs/" in readme


def test_every_results_folder_is_indexed_and_labelled_by_the_one_rule():
    """A result has >= 3 independent units and nothing chosen on the data it is scored on;
    the index's label says what the rule says, and every disclosure is a sentence."""
    index = read_index(RESULTS)
    folders = {p.name for p in RESULTS.iterdir() if p.is_dir()}
    assert folders <= set(index), f"not in results/index.toml: {sorted(folders - set(index))}"
    for name, entry in index.items():
        label = "result" if is_result(entry) else "smoke"
        assert entry["kind"].startswith(label), f"{name}: the rule says {label}"
        assert int(entry["units"]) >= 1, name
        assert all(len(entry[k]) > 20 for k in DISCLOSED if k in entry), name
    assert not is_result({"units": 2}) and not is_result(
        {"units": 5, "chosen_on_scored": "ranges picked on these folds"})


def _options(command: str) -> set[tuple[str, ...]]:
    """A `macrostate-mj` call as its subcommand and (flag, value) pairs: order, the output
    folder, workers, --overwrite and -q do not change what it computes; paths to the reference
    data compare from its root."""
    tokens = [t.split("reference-data/", 1)[-1] for t in shlex.split(command)]
    words, pairs, i = [], set(), 0
    while i < len(tokens):
        token = tokens[i]
        if token in ("-q", "--overwrite", "--json"):
            i += 1
        elif token.startswith("-"):
            value = tokens[i + 1] if i + 1 < len(tokens) and not tokens[i + 1].startswith(
                "--") else ""
            if token not in ("--out", "--workers"):
                pairs.add((token, value))
            i += 2 if value else 1
        else:
            words.append(token)
            i += 1
    return {tuple(words), *pairs}


def _page_folders() -> set[str]:
    """The folders a results page names in a provenance line or a claim."""
    folders = {c["folder"] for chapter in load_claims().values() for c in chapter}
    for page in RESULTS_PAGES:
        folders |= set(re.findall(r"```\{provenance\} (\S+)", (DOCS / f"{page}.md").read_text()))
    return folders


def test_each_page_folder_was_made_by_the_command_its_index_shows():
    """A folder a results page shows was written by its index command (per its manifest's
    argv, defaults as recorded), or the index says why it cannot be rerun as shown."""
    index = read_index(RESULTS)
    for folder in sorted(_page_folders()):
        entry = index[folder]
        manifests = sorted((RESULTS / folder).glob("manifest.json")) or sorted(
            (RESULTS / folder).glob("*/manifest.json"))
        if entry.get("unchecked") or ">" in entry["command"]:   # or JSON lines on stdout
            continue
        assert manifests, f"{folder}: no manifest, and the index does not say why"
        calls = [_options(c.split("macrostate-mj", 1)[1]) for c in
                 re.split(r"&&|;|\bdo\b", entry["command"]) if "macrostate-mj" in c]
        for manifest in manifests:
            argv = json.loads(manifest.read_text()).get("argv")
            if argv is None:
                assert entry.get("code"), f"{manifest}: no argv, and no earlier code disclosed"
                continue
            made = _options(" ".join(shlex.quote(a) for a in argv).replace("$s", ""))
            assert any(made == call or _seeded(made, call) for call in calls), (
                f"{folder}: {manifest.parent.name} ran {argv}, the index shows "
                f"{entry['command']}")


def _seeded(made: set, call: set) -> bool:
    """A loop's call (`--seed $s`) matches each of its runs."""
    return {o for o in made if o[0] != "--seed"} == {o for o in call if o[0] != "--seed"}


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


def test_the_claims_command_and_the_pages_agree_row_for_row(text_build, capsys):
    """`macrostate-mj claims --json` and the chapter pages: the same claims, figures, ours and
    verdicts, in the same order."""
    from clitools import cli_inprocess

    code, out, _ = cli_inprocess(capsys, "claims", "--results", str(RESULTS), "--json")
    printed = [json.loads(line) for line in out.splitlines()]
    shown = [row for page in ("chapter2", "chapter3", "chapter4")
             for expression, rows in _given(text_build, f"reproduction/{page}")
             if expression.startswith("claims ") for row in rows[1:]]
    assert code == 0 and len(printed) == len(shown) == 37
    for claim, row in zip(printed, shown, strict=True):
        assert (row[0], row[1]) == (claim["figure"], claim["claim"])
        assert row[5].startswith(claim["verdict"] + ":"), claim["figure"]
        shown_ours = row[3].split(" ")[0]         # as printed: its rounding bounds the gap
        decimals = len(shown_ours.partition(".")[2])
        assert abs(float(shown_ours) - claim["ours"]) <= 0.5 * 10 ** -decimals + 1e-12, row


