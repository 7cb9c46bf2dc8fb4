"""`bench --json` lines as the docs' table shows them."""

from __future__ import annotations

import json
import math

from macrostate_mj.app.results.sources import (
    load,
    source,
)
from macrostate_mj.core.evidence import Table


@source
def bench(path: str) -> Table:
    """`bench --json` lines: suite, figure, value, limit and ratio."""
    rows = [["suite", "figure", "value", "limit", "ratio", "config"]]
    for line in load(path):  # type: ignore[union-attr]
        config = line.get("config")
        config = json.dumps(config) if isinstance(config, dict) else (config or "")
        rows.append([line["suite"], line["name"], _num(line["value"]) + f" {line['unit']}",
                     _num(line.get("limit")), _num(line.get("ratio")), config])
    return rows


def _num(value: object) -> str:
    if value is None:
        return ""
    value = float(value)  # type: ignore[arg-type]
    if math.isfinite(value) and value.is_integer():
        return str(int(value))
    return f"{value:.3g}" if abs(value) < 100 else f"{value:.0f}"

