"""`macrostate-mj bench` suites: each figure a ratio against a limit measured in the same run.

Every suite returns figures made by `figure`, so that every `bench --json` line has the same
keys: name, value, unit, limit, ratio, config (limit and ratio null where no limit exists).
`ratio` reads the same way for every figure: 1.0 matches the limit, below falls short of it and
above beats it, whether the figure is a rate (ratio = value / limit) or a time (limit / value).
"""

from __future__ import annotations

FIELDS = ("name", "value", "unit", "limit", "ratio", "config")


def figure(name: str, value: float, unit: str, limit: float | None = None, *,
           config: str | dict, lower_is_better: bool = False, **extra: object) -> dict:
    """One bench figure in the shared schema (extra keys, e.g. a stage's share, follow)."""
    ratio = None
    if limit is not None:
        ratio = round(limit / value if lower_is_better else value / limit, 4)
        limit = round(float(limit), 4)
    return {"name": name, "value": round(float(value), 4), "unit": unit, "limit": limit,
            "ratio": ratio, "config": config, **extra}
