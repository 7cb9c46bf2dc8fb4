"""`macrostate-mj bench` suites: each figure a ratio against a limit measured in the same run,
or, where no such limit exists, against a fixed target that says so (`limit_kind`).

Every suite returns figures made by `figure`, so that every `bench --json` line has the same
keys: name, value, unit, limit, limit_kind, ratio, config (limit, limit_kind and ratio null
where no limit exists), and registers itself in `SUITES` (`@SUITES.register("sim", rank=10)`).
`ratio` reads the same way for every figure: 1.0 matches the limit, below falls short of it and
above beats it, whether the figure is a rate (ratio = value / limit) or a time (limit / value).
"""

from __future__ import annotations

from collections.abc import Callable

from macrostate_mj.core.registry import Registry

# Every module of this package registers its suites (`scan`). `bench` runs and lists them by
# the rank each gives where it registers (`@SUITES.register("sim", rank=10)`), the one place a
# suite's place is declared: the modules may be imported in any order (`bench --only srs` or a
# test imports one first), and the cheap, basic loops run before the trainings.
SUITES: Registry[Callable[..., list[dict]]] = Registry("bench suite", packages=[__name__])
FIELDS = ("name", "value", "unit", "limit", "limit_kind", "ratio", "config")
MEASURED, TARGET = "measured", "target"     # a limit measured in the same run, or a fixed goal


def figure(name: str, value: float, unit: str, limit: float | None = None, *,
           config: str | dict, lower_is_better: bool = False, fixed_target: bool = False,
           **extra: object) -> dict:
    """One bench figure in the shared schema (extra keys, e.g. a stage's share, follow);
    `fixed_target`: the limit is a goal set beforehand, not measured in this run."""
    ratio = kind = None
    if limit is not None:
        ratio = round(limit / value if lower_is_better else value / limit, 4)
        limit = round(float(limit), 4)
        kind = TARGET if fixed_target else MEASURED
    return {"name": name, "value": round(float(value), 4), "unit": unit, "limit": limit,
            "limit_kind": kind, "ratio": ratio, "config": config, **extra}
