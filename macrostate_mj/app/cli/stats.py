"""`stats`: ThymioLoc files' statistics, and with `--compare` two files' distributions side by
side (`app.usecases.stats`); this module only parses flags and prints."""

from __future__ import annotations

from pathlib import Path

from macrostate_mj.app.cli.app import app
from macrostate_mj.app.params import (
    CSV,
    InputFile,
    InputFiles,
    OutputFile,
    PxPerCm,
    Switch,
)


@app.command()
def stats(
    csv: list[Path] = InputFiles("ThymioLoc CSV files (real or from `collect`).", CSV),
    px_per_cm: float = PxPerCm,
    as_json: bool = Switch(False, "One JSON object per file (its path, then the figures).",
                           "--json/--table"),
    compare: bool = Switch(False, "Two files (SIM REAL): compare distributions, per robot and "
                           "pooled, with the Kolmogorov-Smirnov distance of each feature."),
    rank: bool = Switch(False, "With --compare: the statistics ranked by how far apart the "
                        "two files are (worst robot's KS; an autocorrelation's ten lags as one), "
                        "with the lab parameters that shape each."),
    plot: Path = OutputFile(None, "With --compare: histograms side by side to this PNG.",
                            (".png",)),
    effects: Path = InputFile(None, "With --rank: an `experiment sim2real --ablate` run's "
                              "results.json; beside each statistic, what switching off each "
                              "parameter group that shapes it does to the sim-only Head error.",
                              (".json",)),
    overwrite: bool = Switch(False, "Replace an existing --plot."),
) -> None:
    """Neighbour spacing, per-robot speed and |turn rate| of ThymioLoc files, side by side;
    with --compare, the distributions of two files and their KS distances."""
    import json
    from dataclasses import asdict

    from rich.console import Console
    from rich.table import Table

    from macrostate_mj.app.usecases import stats as usecase
    from macrostate_mj.core.errors import UserError

    if compare or plot is not None or rank or effects is not None:
        if not compare or len(csv) != 2:
            raise UserError("--compare takes exactly two files (SIM.csv REAL.csv), and --plot "
                            "and --rank need --compare")
        if effects is not None and not rank:
            raise UserError("--effects puts the estimator's sensitivity beside the ranked "
                            "gap; add --rank")
        found = None if effects is None else usecase.ablations(effects)     # before any work
        rows = usecase.compare(csv, px_per_cm, plot, overwrite)
        if rank:
            _print_ranked(csv, usecase.ranked(rows, found), as_json, found is not None)
        else:
            _print_compared(csv, rows, as_json)
        if plot is not None and not as_json and not rank:
            print(f"plot      {plot}")
        return
    found = usecase.file_stats(csv, px_per_cm)
    if as_json:
        for path, stats in found:
            print(json.dumps({"file": str(path), "px_per_cm": px_per_cm, **asdict(stats)}))
        return
    table = Table(title=f"ThymioLoc statistics ({px_per_cm:g} px/cm, 2 Hz)")
    table.add_column("")
    unique = len({p.name for p, _ in found}) == len(found)
    for path, _ in found:       # the shortest label that tells the files apart
        table.add_column(path.name if unique else f"{path.parent.name}/{path.name}",
                         justify="right")
    table.add_row("instances x steps", *(f"{s.n_instances} x {s.n_steps}" for _, s in found))
    table.add_row("robots", *(str(len(s.robots)) for _, s in found))
    table.add_row("spacing cm, mean ± std", *(f"{s.spacing_cm[0]:.1f} ± {s.spacing_cm[1]:.1f}"
                                               for _, s in found))
    table.add_row("spacing cm, 5th-95th pct", *(f"{s.spacing_cm[2]:.1f}-{s.spacing_cm[3]:.1f}"
                                                 for _, s in found))
    robots = max((s.robots for _, s in found), key=len)
    for what, attr, unit in (("speed", "speed_cm_s", "cm/s"), ("|turn|", "turn_deg_s", "°/s")):
        for r in robots:
            table.add_row(f"{what} {r} {unit}", *(f"{getattr(s, attr)[r]:.1f}"
                                                  if r in s.robots else "-" for _, s in found))
    Console().print(table)


def _print_compared(csv: list[Path], rows: list[dict], as_json: bool) -> None:
    """`stats --compare`: each feature's median (mean) in both files, its KS distance and p."""
    import json

    from rich.console import Console
    from rich.table import Table

    if as_json:
        for row in rows:
            print(json.dumps({"files": [str(p) for p in csv], **row}))
        return
    table = Table(title=f"{csv[0].name} vs {csv[1].name}: median (mean) and KS distance")
    for col in ("feature", "robot", csv[0].name, csv[1].name, "KS", "p"):
        table.add_column(col, justify="left" if col in ("feature", "robot") else "right")
    for r in rows:
        if r["feature"].endswith(tuple(f"lag{k}" for k in range(2, 11))) and r["robot"] != "pooled":
            continue            # lags 2..10 pooled only; --json has every row
        table.add_row(r["feature"], r["robot"],
                      *(f"{r['median'][i]:.3g} ({r['mean'][i]:.3g})" for i in (0, 1)),
                      f"{r['ks']:.3f}", f"{r['p']:.2g}")
    Console(width=120).print(table)



def _print_ranked(csv: list[Path], ranked: list[dict], as_json: bool, effects: bool) -> None:
    """`stats --compare --rank`: the gap between two files, its largest statistic first."""
    import json

    from rich.console import Console
    from rich.table import Table

    if as_json:
        for row in ranked:
            print(json.dumps({"files": [str(p) for p in csv], **row}))
        return
    table = Table(title=f"{csv[0].name} vs {csv[1].name}: statistics ranked by the worst "
                  "robot's KS distance")
    columns = ["#", "statistic", "worst", "each robot (pair)", "sum", "shaped in the lab by"]
    for col in columns + (["Head error without it (cm)"] if effects else []):
        table.add_column(col, justify="right" if col in ("#", "sum") else "left")
    for i, r in enumerate(ranked, 1):
        cells = [str(i), r["statistic"], f"{r['worst']} {r['ks'][r['worst']]:.3f}",
                 "  ".join(f"{who} {ks:.3f}" for who, ks in r["ks"].items()),
                 f"{r['sum']:.2f}", ", ".join(r["shaped_by"]) or "-"]
        if effects:
            cells.append("; ".join(f"{g} {d['mean']:+.2f} [{d['low']:+.2f}, {d['high']:+.2f}]"
                                   for g, d in r["effects"].items()) or "-")
        table.add_row(*cells)
    Console(width=150 if not effects else 210).print(table)
