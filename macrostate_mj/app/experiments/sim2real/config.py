"""`experiment sim2real`'s settings: its arms, fits and tuned settings, `Config`, its flags and
profiles."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import typer

from macrostate_mj.app.experiments import Parallel
from macrostate_mj.app.params import (
    MAX_SECONDS,
    REAL_FOLDER,
    Chained,
    Choice,
    InputDir,
    Positive,
    Precision,
    Scenario,
    Seed,
    Switch,
    flag,
)
from macrostate_mj.chain.scenario import ScenarioConfig
from macrostate_mj.chain.scenarios import ScenarioRef, get_scenario
from macrostate_mj.core.errors import UserError
from macrostate_mj.core.paths import real_thymioloc

REAL_DATA = ("retlo",)   # the published datasets it reads (`data fetch NAME`)
PRODUCTS = ["results.json", "sim2real.png"]
ARMS = ("sim", "real", "finetune", "mixed", "finetune-mixed", "finetune-frozen")
MIXING = ("mixed", "finetune-mixed")      # the arms that mix the lab data into the loss
REAL_FILES = ("Train.csv", "Val.csv")
FITS = ("none", "train", "fold")
SIM_SELECT = ("lab", "real")    # what chooses a sim model's checkpoint (`Config.sim_select`)
PLAIN = "none"      # a `randomize` candidate: no ranges (the fitted factors fixed, or the lab)
FINETUNED = ("finetune", "finetune-mixed", "finetune-frozen")   # start from the sim model


@dataclass(frozen=True)
class Tuned:
    """A setting of real-data arms given as candidates (`Config.<name>`): each seed and share
    keeps the arm's model best on the real validation block (`choose_settings`); with several
    candidates, `results.json[table]` gives each one's errors (`cells` per candidate) and the
    summary says how often each was kept (as `label`)."""

    name: str
    arms: tuple[str, ...]
    table: str
    cells: str
    label: str


TUNED = (Tuned("mix_weight", MIXING, "mixes", "weights", "lab share"),
         Tuned("finetune_epochs", FINETUNED, "finetunes", "epochs", "epochs"))


@dataclass(frozen=True)
class Config:
    seeds: int = 5
    folds: int = 5
    fractions: tuple[float, ...] = field(default=(0.1, 0.25, 0.5, 1.0), metadata=flag(Positive(
        None, "Train the real-data arms on this share of the real pool (repeatable).",
        "--fraction", max=1.0), parse=lambda given: tuple(sorted(set(given)))))
    val_share: float = 0.15
    epochs: int = 60
    # the fine-tuned arms' epochs (cosine decay over them); with several, each seed and share
    # keeps the count whose model does best on the real validation block (`finetunes`)
    finetune_epochs: tuple[int, ...] = field(default=(30,), metadata=flag(Positive(
        None, "The fine-tuned arms' epochs on the real data. Repeatable: each seed and share "
        "then keeps the count whose model does best on its real validation block.",
        "--finetune-epochs", max=10_000), parse=lambda given: tuple(sorted(set(given)))))
    finetune_lr: float = 5e-4
    # the mixed arm's lab share of the loss; with several, each seed and share keeps the
    # weight whose model does best on the real validation block that stopped it (`mixes`)
    mix_weight: tuple[float, ...] = field(default=(0.5,), metadata=flag(Positive(
        None, "The mixed arm: the lab data's share of the loss, in (0, 1). Repeatable: each "
        "seed and share then keeps the weight whose model does best on its real validation "
        "block.", "--mix-weight", max=1.0), parse=lambda given: tuple(sorted(set(given)))))
    sim_minutes: float = 100.0
    sim_seed: int = 31
    episode_minutes: float = 5.0
    seed: int = field(default=0, metadata=flag(Seed(0, "The first model seed: model i trains "
                                                    "with seed+i and is tested on real fold i "
                                                    "mod 5.")))
    real: Path = field(default_factory=real_thymioloc, metadata=REAL_FOLDER)
    # the lab the collection is made in
    scenario: ScenarioRef = field(default="lab", metadata=flag(Scenario, default="lab"))
    # a lab collection's folder, instead of collecting one
    sim: Path | None = field(default=None, metadata=flag(InputDir(
        None, "A lab collection folder (Train.csv, Val.csv) to use instead of collecting one "
        "(`collect --scenario lab --robots 3 --split 80/20/0`).")))
    # the lab collection's domain randomization: none, one profile, or candidates (`PLAIN`
    # among them for none) chosen per fold on its real validation block
    randomize: tuple[str, ...] = field(default=(), metadata=flag(typer.Option(
        None, "--randomize", help="A domain-randomization profile or JSON of factors for the "
        "lab collection (e.g. sysid's fitted.json). Repeatable: each fold then picks the "
        "candidate (`none` for no ranges) whose sim model does best on its own real validation "
        "block. The full profile's wider (as the docs' figure) is what `experiment all` "
        "runs."), default=(), shown="none"))
    # which arms to train (a fine-tuned arm trains the sim models)
    arms: tuple[str, ...] = field(default=ARMS[:4], metadata=flag(Choice(
        None, "Train only this arm (repeatable): `--arm sim` asks only how far a lab collection "
        "carries. sim, real, finetune and mixed when none is named.", ARMS, "--arm"),
        parse=lambda given: tuple(a for a in ARMS if a in given)))
    # train on chained Followers too (`TrainConfig.chained`)
    chained: bool = field(default=True, metadata=flag(Chained))
    # cross-validate on Train.csv alone, Val.csv never read: the real Val file stays the sealed
    # test `experiment s2r-sealed` scores once (choose here, then look there)
    train_only: bool = field(default=False, metadata=flag(Switch(
        False, "Cross-validate on the real Train.csv alone, never reading Val.csv: what "
        "chooses a setting before `experiment s2r-sealed` scores it on the sealed Val.csv.",
        "--train-only/--with-val")))
    # what chooses each sim model's checkpoint: the lab's Val.csv (sim data only, the text's
    # protocol), or the fold's real validation block (what a lab with a real file can do; the
    # test block still takes no part)
    sim_select: str = field(default="lab", metadata=flag(Choice(
        None, "What stops each sim model's training and picks its checkpoint: the lab "
        "collection's Val.csv, or the fold's real validation block (the test block takes no "
        "part either way).", SIM_SELECT, "--sim-select")))
    # the trainings' arithmetic (`estimators.precision`)
    precision: str = field(default="fp32", metadata=flag(Precision()))
    # where the lab's factors come from (`FITS`): the scenario as written, a `sysid` fit on the
    # real Train.csv (what a lab with one real file does; under these folds it has seen the
    # test blocks), or one fit per fold on that fold's training blocks only (the nested
    # protocol). The first fit's lab data trains the sim arm and feeds the later arms; each
    # other fit trains a sim-only model of its own, on the same folds (`sim_by_fit`). With a
    # fit, `randomize` names the ranges drawn around the fitted factors.
    fits: tuple[str, ...] = field(default=("none",), metadata=flag(Choice(
        None, "Where the lab's factors come from (repeatable: the first feeds every arm, each "
        "other trains a sim-only model on the same folds): none (the scenario as written), "
        "train (`sysid` on the real Train.csv, which these folds' test blocks are cut from), "
        "fold (one fit per fold on its training blocks only: the nested protocol, what a "
        "held-out test will show). With a fit, --randomize names the ranges drawn around it.",
        FITS, "--fit")))
    sysid_first: int = 16
    sysid_refine: int = 8
    sysid_minutes: float = 30.0
    # groups of lab parameters (`collectors.randomize.PARAMETERS`) switched off in turn, each
    # group's sim-only models paired with the lab's (`ablations`)
    ablate: tuple[tuple[str, ...], ...] = field(default=(), metadata=flag(typer.Option(
        None, "--ablate", help="Switch these lab parameters off (comma-separated, e.g. "
        "frame_hz,frame_jitter; repeatable, one group each): each group trains sim-only models "
        "on a lab collected without them, paired with the lab's own over the folds. Needs "
        "--fit or --randomize."), parse=lambda groups: tuple(
            tuple(n.strip() for n in g.split(",") if n.strip()) for g in groups)))

    @property
    def lab(self) -> ScenarioConfig:
        """The scenario the lab data is collected in, resolved."""
        return get_scenario(self.scenario)

    @property
    def candidates(self) -> tuple[str, ...]:
        """The `randomize` candidates (`PLAIN` alone where none is named)."""
        return self.randomize or (PLAIN,)


PARALLEL = Parallel("collection and trainings")
# not a field's flag: given with --sim, it sizes nothing (`configure` refuses the pair)
FLAGS = {"sim_minutes": Positive(None, "Minutes of lab data to collect.", "--sim-minutes",
                                 max=MAX_SECONDS / 60)}


def configure(config: Config, changes: dict, *, profile: str, workers: int,
              sim_minutes: float | None) -> dict:
    """The command's `--sim-minutes` (refused with `--sim`, whose folder it would not size)."""
    if sim_minutes is None:
        return {}
    if changes.get("sim", config.sim) is not None:
        raise UserError("--sim-minutes sizes the lab collection this command makes; drop it "
                        "or --sim")
    return {"sim_minutes": sim_minutes}


PROFILES = {
    # what `experiment all` runs: every arm on `wider` lab data (the committed
    # results/s2r_mixed); the command's own --randomize replaces it (none by default)
    "full": Config(randomize=("wider",)),
    "quick": Config(seeds=2, fractions=(0.5, 1.0), epochs=2, finetune_epochs=(1,),
                    sim_minutes=6.0, episode_minutes=3.0, sysid_first=2, sysid_refine=1,
                    sysid_minutes=1.0),
}


def missing(config: Config) -> str | None:
    """The input this run cannot start without, if it is absent (`experiment all` skips it)."""
    return None if Path(config.real).is_dir() else \
        f"the real ThymioLoc folder {config.real} (`macrostate-mj data fetch retlo`)"


