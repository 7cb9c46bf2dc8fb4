"""`experiment oc`'s results record: what its `results.json` holds, and its unit."""

from __future__ import annotations

from dataclasses import dataclass, field

from macrostate_mj.core.records import OPTIONAL, Record


@dataclass(frozen=True)
class Results(Record):
    """The one-class tables and figures' numbers: per run (m, split, seed) each method's AUC,
    Table 4.1-4.2 and Fig 4.8 over the runs, Grad-CAM's hits; a run's splits are the
    independent units (its seeds nested in them)."""

    UNIT = "split"

    table4_1_iogen_auc_by_m: dict
    table4_2_auc_m2: dict
    fig4_8_auc_by_bin_m2: dict
    fig4_8_iogen_vs_dsvdd_marks: dict
    fig4_10: dict
    gradcam: dict
    n_unstable: int
    n_unstable_by_bin: dict
    runs: dict[str, dict]
    figures_run: str | None = field(default=None, metadata=OPTIONAL)
    selection_on_test: dict | None = field(default=None, metadata=OPTIONAL)
