"""`experiment s2r-sealed`: the sim-to-real recipe scored on a sealed real test, each look
counted in a ledger.

Every choice is made on the real Train.csv alone. Its last `select_share` (the check block)
picks every model's checkpoint, the lab-only model's included; the rest is the real pool.
The recipe (the lab, its ranges, the minutes, the epochs, the fine-tuning) is this config,
fixed before anything is scored. The real Val.csv is the sealed test: every model is scored
on each of its instances, and nothing else reads it. A look needs a frozen recipe (in a
checkout, no uncommitted change to the packages; an installed wheel is its version) and is
appended to the ledger (`--ledger`; `results/sealed_ledger.jsonl` of the checkout, or of the
working folder): a line when the sealed test is first scored (an interrupted look still
counts), then date, commit, recipe hash, figures and the looks so far at this sealed file
(distinct sealed scores seen: a rescore of the same models is a repeat, not a look).
A setting chosen on a sealed score must never be reported on it: choose on Train's folds
(`experiment sim2real --train-only`, which never opens Val.csv), then look once.

Arms per model seed i (`seed + i`): lab (trained on the lab collection, `collect --randomize
RANGES --minutes MINUTES --split 80/20/0`), real (all of the pool), quarter (the lab model
fine-tuned on contiguous quarter i mod 4 of the pool: seeds see different real data) and
all (the lab model fine-tuned on the whole pool). Each arm against real: the ratio and the
difference of the Head errors, with 95 % intervals from a two-level bootstrap over the test
instances and the model seeds (`core.stats.two_level_bootstrap`): the units are the sealed
test's instances (no two share a row) and the trainings.
"""

from __future__ import annotations

import hashlib
import json
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import typer

from macrostate_mj import __version__
from macrostate_mj.app.experiments import Parallel, Progress, register
from macrostate_mj.app.experiments.sim2real import ModelTask, share, train_models
from macrostate_mj.app.params import (
    REAL_FOLDER,
    Chained,
    Count,
    OutputFile,
    Positive,
    Scenario,
    Seed,
    flag,
)
from macrostate_mj.app.results.sources import (
    record,
    source,
)
from macrostate_mj.chain.scenarios import ScenarioRef, get_scenario
from macrostate_mj.core.errors import UserError
from macrostate_mj.core.evidence import Paired, Table
from macrostate_mj.core.paths import CHECKOUT, real_thymioloc
from macrostate_mj.core.records import Record
from macrostate_mj.core.run import code, config_hash
from macrostate_mj.core.stats import mean_std, two_level_bootstrap
from macrostate_mj.formats.thymioloc import DEFAULT_PX_PER_CM, read_csv

REAL_DATA = ("retlo",)   # the published datasets it reads (`data fetch NAME`)
PRODUCTS = ["results.json"]
SEALED = True       # a look is counted: `experiment all` never takes one
ARMS = ("lab", "real", "quarter", "all")    # what each seed trains, in this order
REFERENCE = "real"                          # what every arm is set against
QUARTER = 0.25


def _default_ledger() -> Path:
    return (CHECKOUT or Path.cwd()) / "results" / "sealed_ledger.jsonl"


@dataclass(frozen=True)
class Config:
    seeds: int = field(default=4, metadata=flag(Count(
        None, "Model seeds per arm (4: each quarter of the pool fine-tunes one).", max=64)))
    seed: int = field(default=0, metadata=flag(Seed(0, "The first model seed.")))
    real: Path = field(default_factory=real_thymioloc, metadata=REAL_FOLDER)
    scenario: ScenarioRef = field(default="lab", metadata=flag(Scenario, default="lab"))
    # the lab collection's ranges: a built-in profile or a JSON file (its content is hashed)
    randomize: str = field(default="wider-rear-timed", metadata=flag(typer.Option(
        None, "--randomize", help="The lab collection's ranges: a built-in profile or a JSON "
        "file (`sysid`'s fitted.json); its content, not its name, is the recipe's."),
        default="wider-rear-timed"))
    sim_minutes: float = field(default=300.0, metadata=flag(Positive(
        None, "Minutes of lab data to collect.", "--sim-minutes", max=10_000)))
    sim_seed: int = 31
    episode_minutes: float = 5.0
    epochs: int = 60
    finetune_epochs: int = 30
    finetune_lr: float = 5e-4
    select_share: float = 0.15      # Train's last share: the check block
    chained: bool = field(default=False, metadata=flag(Chained, default=False))
    precision: str = "fp32"
    ledger: Path = field(default_factory=_default_ledger, metadata=flag(OutputFile(
        None, "The ledger each sealed look is appended to.", (".jsonl",)),
        shown="results/sealed_ledger.jsonl"))

    @property
    def profile(self) -> dict:
        """The ranges as drawn (a file's content, not its name)."""
        from collectors.randomize import Randomization

        return Randomization.parse(self.randomize).profile()


PARALLEL = Parallel("collection and trainings")
PROFILES = {"full": Config(),
            "quick": Config(seeds=2, sim_minutes=4.0, episode_minutes=2.0, epochs=2,
                            finetune_epochs=1)}


def missing(config: Config) -> str | None:
    """The input this run cannot start without (`experiment all` skips it)."""
    return None if Path(config.real).is_dir() else \
        f"the real ThymioLoc folder {config.real} (`macrostate-mj data fetch retlo`)"


def _sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def recipe(config: Config) -> dict:
    """What a sealed figure is of: every setting that shapes a model, the ranges and the
    scenario by content, and the real files by their bytes (the ledger's hash)."""
    return {"scenario": config_hash(get_scenario(config.scenario)),
            "profile": config.profile, "train": _sha(config.real / "Train.csv"),
            "sealed": _sha(config.real / "Val.csv"),
            **{k: getattr(config, k) for k in (
                "seeds", "seed", "sim_minutes", "sim_seed", "episode_minutes", "epochs",
                "finetune_epochs", "finetune_lr", "select_share", "chained", "precision")}}


def validate(config: Config) -> tuple[np.ndarray, np.ndarray]:
    """Refuse bad inputs and an unfrozen recipe in one line, before anything is written or
    scored; Train's and the sealed test's instances (px)."""
    for name, least in (("seeds", 2), ("epochs", 1), ("finetune_epochs", 1)):
        value = getattr(config, name)      # two seeds at least: the intervals resample them
        if isinstance(value, bool) or not isinstance(value, int) or value < least:
            raise UserError(f"{name} {value!r}: a whole number of at least {least}")
    for name, low, high in (("select_share", 0.0, 1.0), ("finetune_lr", 0.0, 1.0),
                            ("sim_minutes", 0.0, 1e4)):
        value = getattr(config, name)
        if not (isinstance(value, int | float) and low < value < high):
            raise UserError(f"{name} {value!r}: must lie in ({low:g}, {high:g})")
    parts = []
    for name in ("Train.csv", "Val.csv"):
        if not (config.real / name).is_file():
            raise UserError(f"--real {config.real} has no {name}; pass the folder of the real "
                            "ThymioLoc Train.csv and Val.csv (`macrostate-mj data fetch retlo`)")
        parts.append(read_csv(config.real / name).poses)
    if parts[0].shape[1:] != parts[1].shape[1:] or parts[0].shape[2] != 3:
        raise UserError(f"--real {config.real}: Train.csv and Val.csv must both hold 3-robot "
                        "instances of the same length")
    pool = len(parts[0]) - _check_size(config, len(parts[0]))
    if len(parts[1]) < 2 or pool < 4:
        raise UserError(f"--real {config.real}: the sealed test needs 2 instances and Train's "
                        f"pool 4 (one a quarter) beside its check block; got {len(parts[1])} "
                        f"and {pool} (Train holds {len(parts[0])}, select_share "
                        f"{config.select_share:g})")
    config.profile                      # noqa: B018  (a bad profile is refused here)
    ledger_entries(config.ledger)       # an unreadable ledger is refused before any look
    frozen()
    return parts[0], parts[1]


def _check_size(config: Config, n_train: int) -> int:
    """How many of Train's last instances pick the checkpoints (the check block)."""
    return max(1, int(round(config.select_share * n_train)))


def frozen() -> dict:
    """The code as it is now, refused unless it is frozen: in a checkout, no uncommitted change
    to the packages, and git able to say so; an installed wheel is its version."""
    made = code()
    if made["dirty"] or made["dirty"] is None and CHECKOUT is not None and \
            (CHECKOUT / ".git").exists():
        raise UserError("a sealed look needs a frozen recipe: commit the code first (the "
                        "packages have uncommitted changes, or git could not tell)")
    return made


def ledger_entries(path: Path) -> list[dict]:
    """The ledger's entries (none where it does not exist yet); one line if unreadable."""
    if not path.is_file():
        return []
    try:
        return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]
    except (OSError, ValueError) as err:
        raise UserError(f"--ledger {path} cannot be read as JSON lines ({err}); give a ledger "
                        "this command wrote, or a new path") from None


def _append(path: Path, entry: dict) -> None:
    """One line appended under an exclusive lock (looks run at once never lose a line)."""
    import fcntl

    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("a") as f:
        fcntl.flock(f, fcntl.LOCK_EX)
        f.write(json.dumps(entry, sort_keys=True) + "\n")


def _lab(config: Config, out: Path, progress: Progress) -> Path:
    """The lab collection (a resumable `collect` run in `out/data/lab`)."""
    from collectors.runner import CollectRequest, collect, finished

    req = CollectRequest(get_scenario(config.scenario), 3, config.sim_minutes,
                         config.sim_seed, out / "data" / "lab", "passive",
                         workers=progress.workers, ray=progress.ray, split="80/20/0",
                         overwrite=True, episode_minutes=config.episode_minutes,
                         randomize=config.randomize)
    if not finished(req):
        collect(req, lambda _, minutes, resumed: progress.report(
            "lab data", minutes, config.sim_minutes, resumed))
    return req.out


def _tasks(config: Config, lab: Path, pool: np.ndarray, check: np.ndarray,
           sealed: np.ndarray, sims: dict[int, Path] | None) -> list[tuple[dict, ModelTask]]:
    """The lab models (`sims` None), or every other arm's, fine-tuned from `sims[seed]`."""
    how = {"chained": config.chained, "precision": config.precision, "per_instance": True}
    tasks = []
    for i in range(config.seeds):
        s = config.seed + i
        if sims is None:
            tasks.append(({"arm": "lab", "seed": s}, ModelTask(
                "sim", s, config.epochs, lab / "Train.csv", check, sealed, **how)))
            continue
        part = share(len(pool), QUARTER, i)
        tasks += [
            ({"arm": "real", "seed": s}, ModelTask("real", s, config.epochs, pool, check,
                                                   sealed, **how)),
            ({"arm": "quarter", "seed": s, "part": [part.start, part.stop]}, ModelTask(
                "finetune", s, config.finetune_epochs, pool[part], check, sealed,
                config.finetune_lr, sims[s], **how)),
            ({"arm": "all", "seed": s}, ModelTask(
                "finetune", s, config.finetune_epochs, pool, check, sealed,
                config.finetune_lr, sims[s], **how))]
    return tasks


def summarize(reports: list[dict], config: Config) -> dict:
    """Per arm the Head error over seeds, and each arm against real (ratio, difference)."""
    by_arm = {a: sorted((r for r in reports if r["arm"] == a), key=lambda r: r["seed"])
              for a in ARMS}
    errors = {a: np.array([r["head_cm_by_instance"] for r in rs]) for a, rs in by_arm.items()}
    out: dict = {"units": "sealed-test instances x model seeds (two-level bootstrap)",
                 "instances": int(errors[REFERENCE].shape[1]), "seeds": config.seeds,
                 "arms": {a: {"head_cm": mean_std([r["head_cm"] for r in rs]),
                              "head_cm_by_seed": {str(r["seed"]): r["head_cm"] for r in rs},
                              # per seed, each sealed instance's error: what compares runs
                              "head_cm_by_instance": {str(r["seed"]): r["head_cm_by_instance"]
                                                      for r in rs},
                              **({"parts": {str(r["seed"]): r["part"] for r in rs}}
                                 if a == "quarter" else {})}
                          for a, rs in by_arm.items()},
                 "against_real": {a: two_level_bootstrap(errors[a], errors[REFERENCE])
                                  for a in ARMS if a != REFERENCE}}
    return out


def looks(entries: list[dict], sealed: str) -> int:
    """How many looks the ledger counts at the sealed file `sealed` (its bytes' hash): distinct
    sealed scores seen, plus each recipe begun at a commit that never finished there (its
    scores may have been read from the cache; a resumed run that finishes is not counted
    twice)."""
    mine = [e for e in entries if e.get("sealed") == sealed]
    seen = {e["scores_hash"] for e in mine if "scores_hash" in e}
    finished = {(e["recipe_hash"], e["commit"]) for e in mine if "scores_hash" in e}
    open_ = {(e["recipe_hash"], e["commit"]) for e in mine
             if e.get("event") == "begun"} - finished
    return len(seen) + len(open_)


def begin(config: Config, made: dict, rec: dict) -> None:
    """A line before the sealed test is first scored (`rec`: the `recipe`): an interrupted
    look still counts."""
    _append(config.ledger, {"event": "begun", "date": time.strftime("%Y-%m-%d", time.gmtime()),
                            "commit": made["commit"], "code_digest": made["digest"],
                            "recipe_hash": config_hash(rec), "sealed": rec["sealed"]})


def look(config: Config, results: dict, made: dict) -> dict:
    """Append this scoring to the ledger; its entry. A look is counted by what was seen: the
    sealed scores (every model's error on every sealed instance), so a rescore of the same
    models is a repeat and adds no look, and models retrained by other code are a new one;
    `made` the code that scored them (`core.run.code()` when the run began; `code_changed`
    where the packages' digest differs at the end); `results` holds the recipe and its hash."""
    scores = config_hash({a: v["head_cm_by_instance"] for a, v in results["arms"].items()})
    sealed = results["recipe"]["sealed"]
    entries = ledger_entries(config.ledger)
    before = {e["scores_hash"] for e in entries
              if e.get("sealed") == sealed and "scores_hash" in e}
    entry = {"date": time.strftime("%Y-%m-%d", time.gmtime()), "commit": made["commit"],
             "version": __version__, "code_digest": made["digest"],
             "code_changed": code()["digest"] != made["digest"],
             "recipe_hash": results["recipe_hash"], "scores_hash": scores,
             "sealed": sealed, "randomize": config.randomize, "repeat": scores in before,
             "figures": {a: {k: round(v, 4) for k, v in results["against_real"][a]["ratio"]
                             .items()} for a in results["against_real"]},
             "head_cm": {a: round(v["head_cm"]["mean"], 4)
                         for a, v in results["arms"].items()}}
    seen = [e for e in [*entries, entry] if e.get("sealed") == sealed and "scores_hash" in e]
    entry["look"] = list(dict.fromkeys(e["scores_hash"] for e in seen)).index(scores) + 1
    entry["looks"] = looks([*entries, entry], sealed)     # which look these scores are; how many
    _append(config.ledger, entry)
    return entry


@dataclass(frozen=True)
class Results(Record):
    """Per arm, each seed's Head error on every sealed test instance and the arms against real
    only (two-level bootstrap over the instances and seeds), the recipe, its hash and the
    ledger's look."""

    UNIT = "test instance"

    instances: int
    pool_instances: int
    check_instances: int
    seeds: int
    units: str
    recipe: dict
    recipe_hash: str
    arms: dict[str, dict]
    against_real: dict[str, dict]
    look: dict


@register
def run(config: Config, out: Path, progress: Progress) -> list[str]:
    """Collect the lab data, train every arm, score the sealed test, log the look."""
    from estimators.retlo.files import pixels_to_world

    with progress.stage("data"):
        train_px, sealed_px = validate(config)
        made = frozen()         # the frozen code, as it was when the look began
        lab = _lab(config, out, progress)
    train = pixels_to_world(train_px, DEFAULT_PX_PER_CM)
    sealed = pixels_to_world(sealed_px, DEFAULT_PX_PER_CM)
    n_check = _check_size(config, len(train))
    pool, check = train[:-n_check], train[-n_check:]
    rec = recipe(config)            # the real files' bytes hashed once
    begin(config, made, rec)
    with progress.stage("models"):
        first = _tasks(config, lab, pool, check, sealed, None)
        total = config.seeds * len(ARMS)
        done = train_models(first, progress, total)
        sims = {meta["seed"]: done[id(t)].folder / "model.pt" for meta, t in first}
        second = _tasks(config, lab, pool, check, sealed, sims)
        done |= train_models(second, progress, total, done)
    reports = [{**meta, **json.loads((done[id(t)].folder / "report.json").read_text())}
               for meta, t in [*first, *second]]
    results = summarize(reports, config)
    results |= {"recipe": rec, "recipe_hash": config_hash(rec),
                "check_instances": n_check, "pool_instances": len(pool)}
    results["look"] = look(config, results, made)
    Results.of(results, "experiment s2r-sealed").write(out)
    progress.record(recipe_hash=results["recipe_hash"], look=results["look"]["look"])
    return summary_lines(results)


def summary_lines(results: dict) -> list[str]:
    seen = results["look"]
    lines = [f"sealed test: {results['instances']} instances, {results['seeds']} seeds per arm "
             f"(look {seen['look']} of {seen['looks']} in the ledger"
             f"{', a repeat' if seen['repeat'] else ''})"]
    for arm, cell in results["arms"].items():
        h = cell["head_cm"]
        against = results["against_real"].get(arm)
        vs = "" if against is None else (
            f"  {against['ratio']['mean']:.2f}x real [{against['ratio']['low']:.2f}, "
            f"{against['ratio']['high']:.2f}]")
        lines.append(f"{arm:<8} Head {h['mean']:.2f} ± {h['std']:.2f} cm{vs}")
    return lines


# Its tables and numbers as the docs show them ----------------------------------------

@source
def sealed(folder: str) -> Table:
    """`experiment s2r-sealed`: each arm's Head error on the sealed test (mean ± std over its
    seeds) and, against real only, the ratio and the difference with their 95 % intervals
    (instances x seeds)."""
    r = record(Results, folder)
    rows = [["arm", "Head error (cm)", "÷ real only [95 %]", "minus real only (cm) [95 %]"]]
    for arm in ARMS:                         # in the experiment's order
        h = r.arms[arm]["head_cm"]
        vs = r.against_real.get(arm)
        compared = ["1", "0"]               # real only against itself
        if vs is not None:
            q, d = vs["ratio"], vs["difference"]
            compared = [f"{q['mean']:.2f} [{q['low']:.2f}, {q['high']:.2f}]",
                        f"{d['mean']:+.2f} [{d['low']:+.2f}, {d['high']:+.2f}]"]
        rows.append([arm, f"{h['mean']:.2f} ± {h['std']:.2f} ({h['n']} seeds)", *compared])
    return rows


@source
def sealed_change(before: str, after: str, arm: str) -> Paired:
    """One arm of two `s2r-sealed` runs on the same sealed test: the later's Head error minus
    the earlier's, with its 95 % interval (`core.stats.two_level_bootstrap`: the instances
    shared, each run's seeds apart)."""
    a, b = ([list(v) for v in record(Results, f).arms[arm][
        "head_cm_by_instance"].values()] for f in (after, before))
    d = two_level_bootstrap(a, b)["difference"]
    units = f"{len(a[0])} test instances, {len(a)} and {len(b)} seeds"
    return Paired(d["mean"], d["low"], d["high"], len(a[0]), units, ".2f", "cm")

