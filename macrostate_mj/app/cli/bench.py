"""`macrostate-mj bench`: speed figures, each a ratio against a limit measured in the same run
(or against a fixed target, which the line says)."""

import importlib
import inspect
import json

from rich.console import Console

from macrostate_mj.app.cli.app import app
from macrostate_mj.app.cli.params import Choice, Count, Scenario, Switch

# name -> "module:function"; each function takes no argument and returns a list of figures made
# by `macrostate_mj.app.bench.figure` (one schema: name, value, unit, limit, limit_kind, ratio,
# config).
SUITES: dict[str, str] = {
    "sim": "macrostate_mj.app.bench.sim:bench_sim",
    "render": "macrostate_mj.app.bench.sim:bench_render",
    "env": "macrostate_mj.app.bench.sim:bench_env",
    "tracker": "macrostate_mj.app.bench.collect:bench_tracker",
    "health": "macrostate_mj.app.bench.collect:bench_health",
    "collect": "macrostate_mj.app.bench.collect:bench_collect",
    "colony": "macrostate_mj.app.bench.colony:bench_colony",
    "retlo": "macrostate_mj.app.bench.retlo:bench_retlo",
    "flow": "macrostate_mj.app.bench.flow:bench_flow",
    "iogen": "macrostate_mj.app.bench.iogen:bench_iogen",
    "srs": "macrostate_mj.app.bench.srs:bench_srs",
    "ensemble": "macrostate_mj.app.bench.ensemble:bench_ensemble",
}


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
        module, func = SUITES[name].split(":")
        with console.status(f"bench {name} ..."):
            fn = getattr(importlib.import_module(module), func)
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
