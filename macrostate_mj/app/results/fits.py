"""The tables of what `sysid` fits (its `fit.json`, `collectors.sysid`) and of what `stats
--compare --rank` ranks (its JSON lines): the gap between a lab and real data, as the docs show
it. Their writers sit below the app (`collectors`) or are a command's own output, so their
tables live here, in the one registry's package."""

from __future__ import annotations

import json
import statistics
import tomllib
from pathlib import Path

from macrostate_mj.app.results.sources import (
    load,
    root,
    source,
)
from macrostate_mj.core.evidence import Code, Table

SYSID_FEATURES = {"spacing_cm": "spacing (cm)", "speed_cm_s": "speed (cm/s)",
                  "wait_share": "time waiting", "jitter_cm": "jitter (cm)",
                  "turn_deg_s": "turn rate (°/s)", "accel_cm_s2": "acceleration (cm/s²)",
                  "heading_change_deg": "heading change (°)",
                  "speed_acf": "speed autocorr. (lag 1; KS over lags 1-10)",
                  "turn_acf": "turn autocorr. (lag 1; KS over lags 1-10)"}


SIGNED = {"turn_deg_s", "heading_change_deg", "accel_cm_s2"}   # medians near 0 say nothing


def _ks_rows(rows: list[dict]) -> dict[tuple[str, str], tuple[float, float, float]]:
    """(feature, robot) -> (KS, sim median, real median), each autocorrelation's lags as the
    fit scores them (KS averaged over lags, medians of lag 1); pooled rows left out."""
    out: dict[tuple[str, str], list] = {}
    for r in rows:
        if r["robot"] == "pooled":
            continue
        family = r["feature"].split("_lag")[0]
        cell = out.setdefault((family, r["robot"]), [[], None, None])
        cell[0].append(r["ks"])
        if "_lag" not in r["feature"] or r["feature"].endswith("_lag1"):
            cell[1], cell[2] = r["median"]
    return {k: (statistics.fmean(v[0]), v[1], v[2]) for k, v in out.items()}


def _chain_order(name: str) -> int:
    """H, F1, F2, ..., T; a pair (`H-F1`) by its first robot."""
    first = name.split("-")[0]
    return 0 if first == "H" else 99 if first == "T" else int(first[1:])


@source
def sysid_ks(folder: str) -> Table:
    """A `sysid` fit's before/after table: per feature and robot the medians (real Val, the
    scenario before, the fit) and the KS distance to the real Train and Val files, before ->
    after; the summed score last."""
    fit = load(f"{folder}/fit.json")
    tables = {(when, split): _ks_rows(fit["rows"][when][split])  # type: ignore[index]
              for when in ("before", "after") for split in ("train", "val")}
    rows = [["feature", "robot", "real Val", "before", "after", "KS Train", "KS Val"]]
    keys = sorted(tables["before", "val"], key=lambda k: (list(SYSID_FEATURES).index(k[0]),
                                                          _chain_order(k[1])))
    for family, robot in keys:
        _, before, real = tables["before", "val"][family, robot]
        after = tables["after", "val"][family, robot][1]
        ks = [f"{tables['before', s][family, robot][0]:.2f} → "
              f"{tables['after', s][family, robot][0]:.2f}" for s in ("train", "val")]
        medians = ["", "", ""] if family in SIGNED else \
            [f"{real:.2f}", f"{before:.2f}", f"{after:.2f}"]
        rows.append([SYSID_FEATURES[family], robot, *medians, *ks])
    rows.append(["summed KS", "", "", "", "",
                 *[f"{fit[s]['before']:.2f} → {fit[s]['after']:.2f}"  # type: ignore[index]
                   for s in ("train", "val")]])
    return rows


@source
def sysid_fits(*folders: str) -> Table:
    """`sysid` fits of one lab under different rules: what each one's scenario file
    (`scenario.toml` beside its fit; none: the lab itself) changes, the summed KS on Train and
    Val before -> after, and the fitted rear-robot factors."""
    rows = [["rule (the scenario's change)", "summed KS Train", "summed KS Val", "k_f ×",
             "k_t ×", "chain cap ×"]]
    for folder in folders:
        fit = load(f"{folder}/fit.json")
        file = root() / folder / "scenario.toml"
        table = tomllib.loads(file.read_text()) if file.is_file() else {}
        changes = [f"{section}.{key} = {json.dumps(value)}" for section, keys in table.items()
                   if isinstance(keys, dict) for key, value in keys.items() if key != "kind"]
        label = Code(", ".join(changes)) if changes else "none (the lab)"
        ks = [f"{fit[s]['before']:.2f} → {fit[s]['after']:.2f}"  # type: ignore[index]
              for s in ("train", "val")]
        fitted = fit["fitted"]  # type: ignore[index]
        rows.append([label, *ks, *(f"{fitted[k]:.2f}" for k in ("k_f", "k_t", "chain_speed"))])
    return rows



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

