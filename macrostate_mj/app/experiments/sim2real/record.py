"""`experiment sim2real`'s results record: what `results.json` holds, and its unit.

Model i (seed `seed + i`) is tested on fold i mod `folds` (`models.fold_of`), so a run's
independent unit is the fold: seeds that share one are averaged to it, and the folds, which
share most of their training data, are Nadeau-Bengio corrected (`design_of`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from macrostate_mj.app.experiments.sim2real.models import fold_of
from macrostate_mj.core.evidence import Design
from macrostate_mj.core.records import OPTIONAL, Record


@dataclass(frozen=True)
class Results(Record):
    """Per arm and share of the real pool, the Head and mean error (cm) over seeds and each
    seed's Head error; the optional tables of the settings each fold chose."""

    UNIT = "fold"

    profile: dict[str, Any]             # the run's Config, as its fields
    real_instances: int
    arms: dict[str, dict[str, Any]]     # arm -> share -> {head_cm, mean_cm, count, by seed}
    sim_over_real: float | None = field(default=None, metadata=OPTIONAL)
    equivalent_real_fraction: dict[str, float] | None = field(default=None, metadata=OPTIONAL)
    finetunes: dict | None = field(default=None, metadata=OPTIONAL)     # epochs chosen
    mixes: dict | None = field(default=None, metadata=OPTIONAL)         # lab shares chosen
    sim_by_fit: dict | None = field(default=None, metadata=OPTIONAL)
    ranges: dict | None = field(default=None, metadata=OPTIONAL)
    ablations: dict | None = field(default=None, metadata=OPTIONAL)
    fits: dict | None = field(default=None, metadata=OPTIONAL)

    def seeds_to_folds(self) -> dict[str, int]:
        """Each seed of this run by the fold it was tested on."""
        first, folds = int(self.profile.get("seed") or 0), int(self.profile["folds"])
        return {str(first + i): fold_of(i, folds)
                for i in range(int(self.profile.get("seeds") or folds))}

    @classmethod
    def design_of(cls, runs: list[Results], seeds: list[str], where: str
                  ) -> tuple[Design, dict[str, str]]:
        """The units of these runs' seeds (runs of other seeds on the same folds pool): the
        folds, seeds that share one nested in it; each seed's key, where `Design.apply` finds
        its fold. Runs that record no folds (an older profile) count each seed a unit."""
        if not all(r.profile.get("folds") for r in runs):
            return Design("seed"), {s: s for s in seeds}
        if len({int(r.profile["folds"]) for r in runs}) > 1:
            raise ValueError(f"{where}: runs on different folds cannot pool")
        fold: dict[str, int] = {}
        for r in runs:
            fold |= r.seeds_to_folds()
        if set(seeds) - set(fold):
            raise ValueError(f"{where}: seeds {sorted(set(seeds) - set(fold))} are not of "
                             "these runs' profiles")
        nested = len({fold[s] for s in seeds}) < len(seeds)
        return (Design("fold", "seed" if nested else "", r"fold\d+" if nested else "",
                       int(runs[0].profile["folds"])),
                {s: f"fold{fold[s]}/seed{s}" for s in seeds})
