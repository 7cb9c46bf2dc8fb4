"""`claims`: the dissertation's claims judged on a checkout's committed results, by one rule."""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

from macrostate_mj.app.cli.app import app
from macrostate_mj.app.params import Choice, InputDir, Switch
from macrostate_mj.app.results import CLAIMS

CHAPTERS = tuple(tomllib.loads(CLAIMS.read_text()))


@app.command("claims")
def claims(
    results: Path = InputDir(Path("results"), "A checkout's results/ folder (with index.toml)."),
    chapter: list[str] = Choice(None, "Only these chapters; repeatable.", CHAPTERS,
                                "--chapter"),
    as_json: bool = Switch(False, "One JSON object per claim instead of the table.",
                           "--json/--table"),
) -> None:
    """Judge every claim of the dissertation on the committed results: the text's value or
    order against ours with its 95 % interval over the independent units results/index.toml
    declares (seeds nested in a split averaged to it, overlapping folds corrected); agree,
    disagree, inconclusive (with the units that would decide it), not comparable or
    qualitative. The rule, its units, corrections and margins, is printed under the table;
    --json gives each row's unit, correction and margin; the docs' chapter pages show the same
    rows."""
    from macrostate_mj.app.results.claims import RULE, counts, judge_all

    judged = judge_all(results, chapter or None)
    if as_json:
        for j in judged:
            print(json.dumps(j.as_json(), ensure_ascii=False))
        return
    for j in judged:
        mark = " (smoke)" if j.smoke else ""
        decide = f"; {j.would_decide} units would decide it" if j.would_decide else ""
        print(f"{j.chapter} {j.figure}: {j.claim}\n  text {j.text or '-'} | ours "
              f"{j.ours_text or '-'}{mark} | {j.verdict}: {j.why}{decide}")
    print(", ".join(f"{n} {v}" for v, n in counts(judged).items()))
    print(RULE)
