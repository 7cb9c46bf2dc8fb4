"""Numbers on the results pages, read from the committed `results/` files when the docs build.

A page never types a measured number. It names where the number lives, by a source of the one
registry (`macrostate_mj.app.results.sources.SOURCES`: the generic ones there, each
experiment's beside it, reading its typed record):

- inline, the role ``{n}`json(srs_text/results.json, configs/passive/1.0000/head_cm, .1f)` ``;
- a table, the directive ``{results-table} srs_table(srs_text, all_predictions_cm)``;
- a chapter's claims, ``{claims} chapter3``: judged by `macrostate_mj.app.results.claims` (what
  `macrostate-mj claims` prints), from its `claims.toml`; ``{claims-summary}`` the rule and counts;
- a folder's provenance, ``{provenance} srs_text``: its command, kind, units and disclosures from
  `results/index.toml` (`macrostate_mj.app.results.provenance`), its date and machine from its
  manifest.

Every source's output is recorded per page in `_numbers.json` beside the built pages;
`tests/docs/test_docs.py` binds each number a results page shows to it (and each inline number
to its file, key and rounding), and fails on any other number it was not told to expect.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

from docutils import nodes
from docutils.parsers.rst import Directive
from sphinx.util.docutils import SphinxRole

from macrostate_mj.app.results import pages
from macrostate_mj.app.results.sources import call, reading
from macrostate_mj.core.errors import UserError
from macrostate_mj.core.evidence import Code, Table

REPO = Path(__file__).resolve().parents[2]
RESULTS = REPO / "results"
NUMBERS = "_numbers.json"       # beside the built pages: every number each page was given


def evaluate(expression: str) -> object:
    """A page's source expression evaluated on the checkout's results."""
    with reading(RESULTS):
        return call(expression)


# Docutils glue -------------------------------------------------------------------------------

def _record(env: object, expression: str, shown: object) -> None:
    """Note what a page was given by which source, for the docs test to bind each number."""
    if isinstance(shown, list):
        shown = [[c.astext() if isinstance(c, nodes.Node | Code) else str(c) for c in row]
                 for row in shown]
    measured = env.__dict__.setdefault("measured_numbers", {})
    measured.setdefault(env.docname, []).append([expression, shown])  # type: ignore[attr-defined]


def _purge(app: object, env: object, docname: str) -> None:
    env.__dict__.get("measured_numbers", {}).pop(docname, None)


def _merge(app: object, env: object, docnames: set[str], other: object) -> None:
    mine = env.__dict__.setdefault("measured_numbers", {})
    for name, rows in other.__dict__.get("measured_numbers", {}).items():
        if name in docnames:
            mine[name] = rows


def _stale(app: object, env: object, added: set, changed: set, removed: set) -> list[str]:
    """Every page that shows numbers is read again each build: its results may have changed
    while its text did not."""
    return sorted(env.__dict__.get("measured_numbers", {}))


def _dump(app: object, error: Exception | None) -> None:
    """`_numbers.json` in the output folder: per page, each source and what it showed."""
    if error is None:
        measured = app.env.__dict__.get("measured_numbers", {})  # type: ignore[attr-defined]
        (Path(app.outdir) / NUMBERS).write_text(json.dumps(measured, indent=1))  # type: ignore[attr-defined]


def _node(cell: object) -> object:
    """A `Code` cell as its literal (and plain tail), any other as it is."""
    if not isinstance(cell, Code):
        return cell
    if not cell.tail:
        return nodes.literal(text=cell.text)
    inline = nodes.inline()
    inline += nodes.literal(text=cell.text)
    inline += nodes.Text(cell.tail)
    return inline


def table_node(rows: Table) -> nodes.table:
    """A plain docutils table: first row the header."""
    table = nodes.table(classes=["results-table", "colwidths-auto"])   # HTML: widths by content
    group = nodes.tgroup(cols=len(rows[0]))
    table += group
    # Widths matter to the text builder (the docs test reads its output): a column as wide as
    # its longest cell, up to 40 characters, so no number is broken across lines.
    for j in range(len(rows[0])):
        width = max(len(c.astext() if isinstance(c, nodes.Node | Code) else str(c)) for c in
                    (row[j] for row in rows))
        group += nodes.colspec(colwidth=min(max(width, 3), 40))
    for part, chunk in ((nodes.thead(), rows[:1]), (nodes.tbody(), rows[1:])):
        for cells in chunk:
            row = nodes.row()
            for cell in cells:
                entry = nodes.entry()
                cell = _node(cell)
                if isinstance(cell, nodes.Node):
                    para = nodes.paragraph()
                    para += cell
                    entry += para
                else:
                    entry += nodes.paragraph(text=str(cell))
                row += entry
            part += row
        group += part
    return table


class NumberRole(SphinxRole):
    """``{n}`source(args)` ``: one quantity, printed as its source formats it."""

    def run(self) -> tuple[list[nodes.Node], list[nodes.system_message]]:
        try:
            text = str(evaluate(self.text))
        except (ValueError, KeyError, IndexError, TypeError) as exc:
            msg = self.inliner.reporter.error(f"{self.text}: {exc}", line=self.lineno)
            return [nodes.problematic(self.rawtext, self.rawtext)], [msg]
        _record(self.env, self.text, text)
        return [nodes.inline(self.rawtext, text, classes=["measured"])], []


class ResultsTable(Directive):
    """``{results-table} source(args)``: a table computed from results files."""

    required_arguments = 1
    final_argument_whitespace = True

    def run(self) -> list[nodes.Node]:
        try:
            rows = evaluate(self.arguments[0])
        except (ValueError, KeyError, IndexError, TypeError) as exc:
            raise self.error(f"{self.arguments[0]}: {exc}") from exc
        _record(self.state.document.settings.env, self.arguments[0], rows)
        return [table_node(rows)]  # type: ignore[arg-type]


def _judged(directive: Directive, build: Callable[[], object]) -> object:
    """What `build` makes of the results, a bad claims file or folder as the page's error."""
    try:
        return build()
    except UserError as exc:
        raise directive.error(str(exc)) from exc


class Claims(Directive):
    """``{claims} chapter``: the chapter's claims judged by the code `macrostate-mj claims`
    runs (`pages.chapter`), with the results folder they share."""

    required_arguments = 1

    def run(self) -> list[nodes.Node]:
        rows, folder = _judged(self, lambda: pages.chapter(RESULTS, self.arguments[0]))
        _record(self.state.document.settings.env, f"claims {self.arguments[0]}", rows)
        out: list[nodes.Node] = [table_node(rows)]
        if folder:
            para = nodes.paragraph(text="Results: ")
            para += nodes.literal(text=f"results/{folder}")
            out.append(para)
        return out


class ClaimsSummary(Directive):
    """``{claims-summary}``: the rule, stated once, each judged folder's units, and each
    chapter's count of verdicts (`pages.summary`)."""

    def run(self) -> list[nodes.Node]:
        units, rows = _judged(self, lambda: pages.summary(RESULTS))
        env = self.state.document.settings.env
        _record(env, "claims-summary", rows)
        _record(env, "claims-units", units)
        return [nodes.paragraph(text=pages.RULE), table_node(units),
                nodes.paragraph(text=pages.RESULT_RULE), table_node(rows)]


class ClaimsChanges(Directive):
    """``{claims-changes} file``: the verdicts before the rule (`claims --json` as it printed
    them, kept in `file` beside the page) against today's (`pages.changes`)."""

    required_arguments = 1

    def run(self) -> list[nodes.Node]:
        here = Path(self.state.document.current_source).parent
        before = [json.loads(line) for line in (here / self.arguments[0]).read_text()
                  .splitlines() if line.strip()]
        rows, changed = _judged(self, lambda: pages.changes(RESULTS, before,
                                                            self.arguments[0]))
        env = self.state.document.settings.env
        _record(env, "claims-changes counts", rows)
        _record(env, "claims-changes", changed)
        return [table_node(rows), table_node(changed)]


class Experiments(Directive):
    """``{experiments}``: every registered experiment, a row generated from its module
    (`app.experiments.catalogue`): adding an experiment adds its row."""

    def run(self) -> list[nodes.Node]:
        from macrostate_mj.app.experiments import catalogue

        rows = _judged(self, lambda: catalogue(RESULTS))
        _record(self.state.document.settings.env, "experiments", rows)
        return [table_node(rows)]


class Provenance(Directive):
    """``{provenance} folder``: where a results folder comes from and what kind of figure it
    is (`pages.provenance`), and its command."""

    required_arguments = 1

    def run(self) -> list[nodes.Node]:
        folder = self.arguments[0]
        parts, command = _judged(self, lambda: pages.provenance(RESULTS, folder))
        para = nodes.paragraph(classes=["provenance"])
        _record(self.state.document.settings.env, f"provenance {folder}", [[*parts, command]])
        para += nodes.emphasis(text=" · ".join(p for p in parts if p) + ". ")
        para += nodes.literal(text=command)
        return [para]


def setup(app: object) -> dict:
    app.add_role("n", NumberRole())  # type: ignore[attr-defined]
    app.add_directive("results-table", ResultsTable)  # type: ignore[attr-defined]
    app.add_directive("claims", Claims)  # type: ignore[attr-defined]
    app.add_directive("claims-summary", ClaimsSummary)  # type: ignore[attr-defined]
    app.add_directive("claims-changes", ClaimsChanges)  # type: ignore[attr-defined]
    app.connect("env-purge-doc", _purge)  # type: ignore[attr-defined]
    app.connect("env-merge-info", _merge)  # type: ignore[attr-defined]
    app.connect("build-finished", _dump)  # type: ignore[attr-defined]
    app.connect("env-get-outdated", _stale)  # type: ignore[attr-defined]
    app.add_directive("provenance", Provenance)  # type: ignore[attr-defined]
    app.add_directive("experiments", Experiments)  # type: ignore[attr-defined]
    return {"parallel_read_safe": True, "version": "1"}
