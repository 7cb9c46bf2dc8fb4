"""`stats` as a use case: the statistics of ThymioLoc files, and with `--compare` the
distributions of two files, their KS distances and, with `--rank`, the statistics ranked by the
gap (`collectors.gap`), with what switching each parameter group off does to a sim-to-real run's
Head error beside (`--effects`, read through `experiment sim2real`'s record, found by name).
The command only parses flags and prints; the ranked rows it prints with `--json` are what the
docs' gap table reads (`gap_ranked`, below)."""

from __future__ import annotations

import json
from pathlib import Path

from macrostate_mj.app.results.sources import RECORDS, root, source
from macrostate_mj.core.errors import UserError
from macrostate_mj.core.evidence import Table
from macrostate_mj.core.records import RecordError


def file_stats(csv: list[Path], px_per_cm: float) -> list[tuple[Path, object]]:
    """Each file with its chain statistics (`formats.thymioloc.chain_stats`)."""
    from macrostate_mj.formats.thymioloc import chain_stats, read_csv

    return [(p, chain_stats(read_csv(p).poses, px_per_cm)) for p in csv]


def compare(csv: list[Path], px_per_cm: float, plot: Path | None = None,
            overwrite: bool = False) -> list[dict]:
    """The two files' feature distributions compared, per robot and pooled (KS distance), and
    their histograms side by side in `plot`."""
    from macrostate_mj.core.io import check_writable_file
    from macrostate_mj.formats import motion_stats
    from macrostate_mj.formats.thymioloc import read_csv

    if plot is not None:
        check_writable_file(plot, overwrite, "--plot")
    poses = [read_csv(p).poses for p in csv]
    motion_stats.check_comparable(poses[0].shape, poses[1].shape, (csv[0].name, csv[1].name))
    feats = [motion_stats.features(p, px_per_cm) for p in poses]
    rows = motion_stats.compare(*feats)
    if plot is not None:
        from viz.compare_figures import compare_figure

        compare_figure(plot, *feats, rows, (csv[0].name, csv[1].name))
    return rows


def ranked(rows: list[dict], effects: dict | None = None) -> list[dict]:
    """The compared statistics ranked by the worst robot's KS distance, with a sim-to-real
    run's ablations beside each (`effects`, read by `ablations`)."""
    from collectors.gap import ranked_gap

    return ranked_gap(rows, effects)


def ablations(path: Path) -> dict:
    """The `ablations` of an `experiment sim2real --ablate` run (its results.json, or its
    folder), read through its record."""
    record = RECORDS["sim2real"]            # `experiment sim2real`'s, by name: no import up
    file = path / record.FILE if path.is_dir() else path
    try:
        found = record.of(json.loads(file.read_text()), str(file)).ablations  # type: ignore[attr-defined]
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise UserError(f"--effects {path}: cannot read it ({exc})") from exc
    except RecordError as exc:
        raise UserError(f"--effects: no ablations in it: {exc}") from exc
    if not found:
        raise UserError(f"--effects {path}: no ablations in it; pass the results.json of an "
                        "`experiment sim2real --ablate ...` run")
    return found


@source
def gap_ranked(*files: str) -> Table:
    """Ranked sim-to-real gaps (`stats --compare --rank --json` files, one per lab): per
    statistic the worst robot's KS distance in each, in the first file's order."""
    runs = [[json.loads(line) for line in (root() / f).read_text().splitlines()]
            for f in files]
    effects = "effects" in runs[0][0]     # `--effects`: the first file's, beside each row
    stems = [Path(f).stem for f in files]
    named = stems if len(set(stems)) == len(stems) else [f.removesuffix(".jsonl") for f in files]
    rows = [["statistic", *named, "shaped in the lab by",
             *(["Head error without it (cm)"] if effects else [])]]
    for r in runs[0]:
        cells = []
        for run in runs:
            other = next(x for x in run if x["statistic"] == r["statistic"])
            cells.append(f"{other['ks'][other['worst']]:.2f} ({other['worst']})")
        shown = [f"{g} {d['mean']:+.2f} [{d['low']:+.2f}, {d['high']:+.2f}]"
                 for g, d in r.get("effects", {}).items()]
        rows.append([r["statistic"], *cells, ", ".join(r["shaped_by"]),
                     *(["; ".join(shown)] if effects else [])])
    rows.append(["summed", *(f"{sum(x['sum'] for x in run):.2f}" for run in runs), "",
                 *([""] if effects else [])])
    return rows

