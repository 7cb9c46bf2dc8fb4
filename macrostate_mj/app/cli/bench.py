"""`macrostate-mj bench`: speed figures, each a ratio against a limit measured in the same run
(or against a fixed target, which the line says)."""

import inspect
import json

from rich.console import Console

from macrostate_mj.app.bench import SUITES
from macrostate_mj.app.cli.app import app
from macrostate_mj.app.params import Choice, Count, Scenario, Switch


@app.command()
def bench(
    only: list[str] = Choice(None, "Suites to run (repeatable); default all.", tuple(SUITES),
                             "--only"),
    as_json: bool = Switch(False, "One JSON object per line, nothing else.", "--json/--table"),
    scenario: str = Scenario,
    robots: int = Count(None, "Chain length of the sim and render suites (default: 5)."),
) -> None:
    """Measure our loops against their bare limits (simulation, rendering, tracking, ...).
    `--scenario` and `--robots` set the world of the suites that take one (sim, render)."""
    names = only or list(SUITES)
    console, results = Console(stderr=True), Console()   # progress on stderr, figures on stdout
    for name in names:
        with console.status(f"bench {name} ..."):
            fn = SUITES[name]
            given = {"scenario": scenario, "robots": robots}
            figures = fn(**{k: v for k, v in given.items()
                            if v is not None and k in inspect.signature(fn).parameters})
        for fig in figures:
            fig = {"suite": name, **fig}
            if as_json:
                print(json.dumps(fig), flush=True)
            else:
                ratio = (f"  ratio {fig['ratio']:.3f} vs {fig['limit_kind']} {fig['limit']:.4g}"
                         if fig["ratio"] is not None else "")
                results.print(f"{fig['name']:<40} {fig['value']:>12.4g} {fig['unit']}{ratio}",
                              soft_wrap=True)
