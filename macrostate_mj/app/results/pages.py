"""What the docs' claims and provenance directives show, as tables: the chapters' judged claims,
the rule with each folder's units and the verdicts' counts, the verdicts before and after the
rule, and a results folder's provenance line. The directives (`docs/_ext/results.py`) only turn
these into nodes and record what each page was given."""

from __future__ import annotations

import json
from datetime import UTC, datetime
from pathlib import Path

from macrostate_mj.app.results.claims import (
    RULE,
    VERDICTS,
    counts,
    design_of,
    judge_all,
    load_claims,
)
from macrostate_mj.app.results.provenance import (
    RESULT_RULE,
    disclosures,
    is_result,
    read_index,
)
from macrostate_mj.core.evidence import ClaimsError, Code, Table
from macrostate_mj.core.run import MANIFEST


def chapter(results: Path, name: str) -> tuple[Table, str | None]:
    """A chapter's claims judged (what `macrostate-mj claims` prints): the text's value against
    ours with its interval and n, what it was compared with, and the verdict; with the one
    results folder they all read, if they share one (else a column names each row's)."""
    judged = judge_all(results, [name])
    folders = sorted({j.folder for j in judged if j.folder})
    shared = len(folders) == 1
    header = ["figure", "claim", "dissertation", "ours [95 % interval], n", "compared with",
              "verdict", "finding"]
    rows: Table = [header if shared else [*header[:6], "results", header[6]]]
    for j in judged:
        decide = f"; {j.would_decide} units would decide it" if j.would_decide else ""
        row = [j.figure, j.claim, j.text, j.ours_text + (" (smoke)" if j.smoke else ""),
               j.comparator, f"{j.verdict}: {j.why}{decide}", j.finding]
        if not shared:
            row.insert(6, j.folder or "")
        rows.append(row)
    return rows, folders[0] if shared else None


def summary(results: Path) -> tuple[Table, Table]:
    """Each judged folder's units, nesting, correction and what its units share (as
    results/index.toml declares them), and each chapter's count of verdicts (`RULE` and
    `RESULT_RULE` are said beside them)."""
    judged = judge_all(results)
    chapters = list(dict.fromkeys(j.chapter for j in judged))
    rows: Table = [["chapter", *VERDICTS, "claims"]]
    for name in [*chapters, "all"]:
        mine = [j for j in judged if name in ("all", j.chapter)]
        rows.append([name, *counts(mine).values(), len(mine)])
    index = read_index(results)
    units: Table = [["results", "unit", "nested in it (averaged)", "correction",
                     "every unit shares"]]
    seen: set[tuple] = set()
    for claims in load_claims().values():
        for claim in claims:
            d = design_of(claim, index)
            if (claim["folder"], d) in seen:
                continue
            seen.add((claim["folder"], d))
            units.append([Code(claim["folder"]),
                          d.unit + (" (one training)" if d.trainings == 1 else ""),
                          d.within or "-", d.correction(), d.shared or "-"])
    return units, rows


def changes(results: Path, before: list[dict], where: str) -> tuple[Table, Table]:
    """The verdicts before the units, corrections and margins of the rule (`claims --json` as
    it printed them, `before`) against today's, counted per chapter, and every claim whose
    verdict changed with today's reason."""
    after = judge_all(results)
    was = {(b["chapter"], b["figure"], b["claim"]): b for b in before}
    rows: Table = [["chapter", *[f"{v} (before → after)" for v in VERDICTS]]]
    for name in dict.fromkeys(j.chapter for j in after):
        old = [b for b in before if b["chapter"] == name]
        new = counts([j for j in after if j.chapter == name])
        rows.append([name, *[f"{sum(b['verdict'] == v for b in old)} → {new[v]}"
                             for v in VERDICTS]])
    changed: Table = [["chapter", "figure", "claim", "before", "after", "why"]]
    for j in after:
        b = was.get((j.chapter, j.figure, j.claim))
        if b is None:
            raise ClaimsError(f"{j.figure} ({j.claim}) is not in {where}")
        if b["verdict"] != j.verdict:
            changed.append([j.chapter, j.figure, j.claim, f"{b['verdict']}, n {b['n']}",
                            f"{j.verdict}, n {j.n} ({j.unit})", j.why])
    return rows, changed


def _units(entry: dict) -> str:
    """How many units a folder's figures rest on, and which (as `results/index.toml` declares
    them): independent ones, or folds and splits whose training data overlap."""
    unit = entry.get("unit")
    if not unit:
        return f"{entry['units']} independent units"
    what = f"{entry['units']} {unit}s"
    if entry.get("folds") or entry.get("split_ratio"):
        return what + " (their training data overlap: intervals Nadeau-Bengio corrected)"
    return what + " (independent)"


def provenance(results: Path, folder: str) -> tuple[list[str], str]:
    """Where a results folder comes from and what kind of figure it is: its path, kind, units
    and disclosures, the date, machine and code of its manifest; and its command."""
    entry = read_index(results).get(folder)
    if entry is None:
        raise ClaimsError(f"results/{folder} is not in results/index.toml")
    if entry["kind"].startswith("result") != is_result(entry):
        raise ClaimsError(f"results/index.toml [{folder}]: its kind contradicts the rule")
    parts = [f"results/{folder}", entry["kind"], _units(entry), *disclosures(entry)]
    manifest = results / folder / MANIFEST
    if manifest.is_file():
        data = json.loads(manifest.read_text())
        parts.append(datetime.fromtimestamp(data["created_unix"], UTC).strftime("%Y-%m-%d"))
        machine = data.get("machine")
        if isinstance(machine, dict):
            parts.append(str(machine.get("cpu") or machine.get("processor") or ""))
        made = data.get("code")
        if made is None:        # made before manifests kept it: say so, never guess
            parts.append("code not recorded (an earlier manifest)")
        elif made.get("commit"):
            parts.append(f"code {made['commit'][:7]}" + (" with changes" if made["dirty"]
                                                        else ""))
    return parts, entry["command"]


__all__ = ["RESULT_RULE", "RULE", "changes", "chapter", "provenance", "summary"]
