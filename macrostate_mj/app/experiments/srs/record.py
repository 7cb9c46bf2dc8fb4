"""`experiment srs`'s results record: what its `results.json` holds, and its unit."""

from __future__ import annotations

from dataclasses import dataclass

from macrostate_mj.core.records import Record


@dataclass(frozen=True)
class Results(Record):
    """Chapter 3's errors per configuration and budget share (mean ± std over datasets and
    model seeds), the baseline, and the distances of Fig 3.7; the datasets are the independent
    units (each model's report in `models/`)."""

    UNIT = "dataset"

    profile: dict
    baseline: dict
    configs: dict[str, dict]
    distances: dict
