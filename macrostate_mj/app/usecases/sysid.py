"""System identification of a scenario against real ThymioLoc data.

What is fitted: factors on the scenario's own values (`collectors.randomize` names, so a fit is
a fixed-factor profile that `collect --randomize fitted.json` reads): the Follower and Tail
gains, the heading gain, the Head's and the chain's speed caps, the lab wait rule's slack, the
tracker's position noise (`marker_jitter`) and the Head's share of it (`head_jitter_scale`),
the camera's frame rate; and values added to the scenario's zero: the frames' timing jitter
(s), the rows' alternation (s), the rear robots' start gap (m), the wheels' radius spread and
the markers' offset (m). The rear robots' rule when nearer than d to the robot ahead
(`follow_hold`: how much nearer before they back off; the real ones could not reverse, seed
§2.6.2.1) and how the Head drives (`head_turn_speed`, `max_turn`) are fitted too, under one
constraint: a candidate whose parked chain does not stand still (`chain.parked`; with stiff
gains, a rear robot that may back off turns on the spot) is refused, whatever its score.
What is minimised: the summed two-sample KS distance (`formats.motion_stats`) between a seeded
collection and the real Train file, over every per-robot (or per-pair) row of every feature;
the ten lags of each autocorrelation count as one feature (their KS averaged), so they do not
outweigh the rest twentyfold.
How: every candidate is a collection with the same seed (common random numbers: the same starts
and Head routes, so the scores differ by the parameters, not by luck). Stage 1 draws scrambled
Sobol points over log-factors in each parameter's box (`BOUNDS`), with the scenario's own
values (all factors 1) as point 0; stage 2 draws Sobol points in a box a quarter as wide around
stage 1's best. The best of both is checked on the real Val file against the unfitted
scenario. Each candidate is cached (its collection and its score), so an interrupted fit
resumes.
"""

from __future__ import annotations

import json
import statistics
import tomllib
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from collectors.gap import ranked_gap
from collectors.randomize import ABSOLUTE, Randomization, around, randomized_scenario
from collectors.runner import CollectRequest, collect, finished
from macrostate_mj.app.results.sources import load, root, source
from macrostate_mj.chain.scenario import ScenarioConfig
from macrostate_mj.chain.scenarios import SCENARIOS, ResolvesScenario
from macrostate_mj.core.cache import TaskCache, task_key
from macrostate_mj.core.errors import UserError
from macrostate_mj.core.evidence import Code, Table
from macrostate_mj.core.io import write_json_atomic, write_text_atomic
from macrostate_mj.core.run import config_hash
from macrostate_mj.formats import motion_stats
from macrostate_mj.formats.instances import INSTANCE_STEPS
from macrostate_mj.formats.thymioloc import DEFAULT_PX_PER_CM, read_csv

# Each factor's box: 0.6-1.6 around the scenario's value, wider where the real data lies
# farther off. The real rear robots drive at about the Head's speed and stop once within their
# spacing (their median speed jumps from 1.5 to 6 cm/s between gaps of 29 and 31 cm), which the
# lab's proportional rule reaches only with gains several times its own and a speed cap near the
# Head's; the real Head's marker jitter is lower than the others' (docs: decisions/sysid).
# The camera's frame timing: frames of uneven age make a logged speed alternate from row to
# row, as the real Head's does (lag-1 autocorrelation -0.35, lag-2 +0.29) and a steady 4 fps
# under a 2 Hz log cannot (the real rear robots' does not alternate, so it is not the whole
# story: docs, reproduction/sim-to-real); the rear robots' start gap (m), which keeps a stiff
# parked chain still; how the robots differ (each wheel's radius, each marker's place).
# The `ABSOLUTE` ones' boxes are in their units (s, m) from 0 (the scenario as written), the
# others' factors; a jitter stays under the fastest frame period (1 / (4 Hz x 1.6) = 0.156 s).
# The rear robots' rule when nearer than d to the robot ahead (`follow_hold`, m: from backing
# off at once, 0, to stopping, the lab's spacing) and how the Head drives (through its turns,
# `head_turn_speed`; how far it turns for its next waypoint, `max_turn`: 45-180 degrees) are
# fitted too; a candidate whose parked chain does not stand still (`chain.parked`) is refused
# whatever its score. The rows' shared timing (`frame_alternation`, s: every other row's frames
# that much earlier) reproduces the alternation every real robot's speed shows with the Head's
# (docs: reproduction/sim-to-real); a candidate's alternation is capped below its frame period
# less its jitter (`feasible`), where the box is not a rectangle.
BOUNDS: dict[str, tuple[float, float]] = {
    "k_f": (0.6, 10.0), "k_t": (0.6, 10.0), "k_omega": (0.6, 1.6), "head_speed": (0.6, 1.6),
    "chain_speed": (0.3, 1.6), "wait_slack": (0.6, 1.6), "marker_jitter": (0.6, 1.6),
    "head_jitter_scale": (0.5, 1.6), "frame_hz": (0.6, 1.6), "frame_jitter": (0.0, 0.15),
    "follow_start": (0.0, 0.04), "wheel_spread": (0.0, 0.05), "marker_offset": (0.0, 0.01),
    "follow_hold": (0.0, 0.3), "head_turn_speed": (0.0, 1.0), "max_turn": (0.25, 1.0),
    "frame_alternation": (0.0, 0.1)}
FITTED = tuple(BOUNDS)
CHECK_SHARE = 0.15         # without a check file, the last share of the real file checks
SCORE_VERSION = 1          # bump when the motion features or the score change
PARKED_VERSION = 1         # bump when `chain.parked`'s check changes


@dataclass(frozen=True)
class SysidConfig(ResolvesScenario):
    scenario: ScenarioConfig = field(default_factory=lambda: SCENARIOS["lab"])  # or a name, a file
    robots: int = 3
    minutes: float = 30.0      # simulated driving per candidate
    seed: int = 1
    first: int = 16            # stage-1 candidates (the scenario's own values among them)
    refine: int = 8            # stage-2 candidates
    shrink: float = 0.25       # stage 2's box, as a share of stage 1's
    episode_minutes: float = 5.0
    workers: int = 1
    only: tuple[str, ...] = ()  # fit these alone (the others at the scenario's values)
    base: str | None = None     # ranges every candidate is drawn within (`around` its factors)

    @property
    def fitted(self) -> tuple[str, ...]:
        """The parameters searched, in `FITTED`'s order."""
        return tuple(k for k in FITTED if k in self.only) if self.only else FITTED

    def __post_init__(self) -> None:
        super().__post_init__()
        unknown = [k for k in self.only if k not in FITTED]
        if unknown:
            raise UserError(f"sysid --only {', '.join(unknown)}: choose among "
                            f"{', '.join(FITTED)}")
        if self.base is not None:
            Randomization.parse(self.base)          # refused here, in one line

    def profile(self, factors: dict[str, float]) -> dict:
        """A candidate's collection profile: its factors, or the `base` ranges around them."""
        if self.base is None:
            return factors
        return around(factors, Randomization.parse(self.base).profile())


def identity(cfg: SysidConfig) -> dict:
    """What a fit is made from: its settings, the scenario by name and by content (a cache
    keyed by the name alone would keep scoring a lab file that has since changed); `only` and
    `base` where set."""
    scenario = cfg.scenario
    skip = ("workers", "scenario", *(k for k in ("only", "base") if not getattr(cfg, k)))
    out = {**{k: v for k, v in asdict(cfg).items() if k not in skip},
           "scenario": scenario.name, "scenario_hash": config_hash(scenario)}
    if cfg.only:
        out["only"] = list(cfg.fitted)      # as searched, whatever order they were named in
    if cfg.base is not None:
        out["base"] = Randomization.parse(cfg.base).profile()   # by content, not by name
    return out


def score(rows: list[dict]) -> float:
    """Summed KS over per-robot rows; the lags of one autocorrelation family averaged
    (`motion_stats.rank`'s sums, over every statistic)."""
    return sum(r["sum"] for r in motion_stats.rank(rows))


def _sobol(n: int, seed: int, dims: int) -> np.ndarray:
    """The first n of a scrambled Sobol sequence of power-of-two length, in [0, 1)."""
    from scipy.stats import qmc

    m = max(0, int(np.ceil(np.log2(max(n, 1)))))
    return qmc.Sobol(dims, scramble=True, seed=seed).random_base2(m)[:n]


def box(names: tuple[str, ...] = FITTED) -> tuple[np.ndarray, np.ndarray]:
    """The search box's lower and upper corners, in `names`' order: log-factors, and the
    `ABSOLUTE` parameters' values as they are (0, the scenario as written, is the origin of
    both)."""
    return tuple(np.array([BOUNDS[k][i] if k in ABSOLUTE else np.log(BOUNDS[k][i])
                           for k in names]) for i in (0, 1))


def values(x: np.ndarray, names: tuple[str, ...] = FITTED) -> dict[str, float]:
    """A point of the box as the profile `collect --randomize` reads (factors, and values)."""
    return {k: float(round(v if k in ABSOLUTE else np.exp(v), 4))
            for k, v in zip(names, x, strict=True)}


def point(fitted: dict[str, float], names: tuple[str, ...] = FITTED) -> np.ndarray:
    """`values`' inverse."""
    return np.array([fitted[k] if k in ABSOLUTE else np.log(fitted[k]) for k in names])


def feasible(factors: dict[str, float], scenario: ScenarioConfig) -> dict[str, float]:
    """The factors with the rows' alternation capped below the candidate's frame period less
    its jitter (the scenario refuses more: frames would overtake each other)."""
    if not factors.get("frame_alternation"):
        return factors
    period = min(1 / (scenario.camera_hz * factors.get("frame_hz", 1.0)), 1 / scenario.log_hz)
    room = period - scenario.frame_jitter - factors.get("frame_jitter", 0.0)
    cap = float(np.floor(0.95 * (room - scenario.frame_alternation) * 1e4) / 1e4)
    return {**factors, "frame_alternation": min(factors["frame_alternation"], max(cap, 0.0))}


def candidates(cfg: SysidConfig, centre: np.ndarray | None = None) -> np.ndarray:
    """Points of the box (k, len(cfg.fitted)): stage 1 over the whole box (point 0 = no
    change to the fitted values), or stage 2 around `centre`."""
    lo, hi = box(cfg.fitted)
    if centre is None:
        pts = _sobol(cfg.first - 1, cfg.seed, len(lo))
        return np.vstack([np.zeros(len(lo)), lo + pts * (hi - lo)])
    half = cfg.shrink * (hi - lo) / 2
    pts = _sobol(cfg.refine, cfg.seed + 1, len(lo))
    return np.clip(centre - half + pts * 2 * half, lo, hi)


def evaluate(factors: dict[str, float], out: Path, cfg: SysidConfig, real: dict,
             real_poses: np.ndarray) -> dict:
    """Collect with these fixed factors (a collection of its own, resumable, in a folder named
    by what it is made from, so fits against other real data share it) and score it against
    the real features (a cached task keyed by the collection's identity and the real poses)."""
    made_of = {"factors": factors, "config": identity(cfg)}
    folder = out / "candidates" / task_key("sysid-collect", 1, made_of)[:16]
    cache = TaskCache(out / "cache")

    def compute() -> dict[str, bytes]:
        folder.mkdir(parents=True, exist_ok=True)
        profile = folder / "factors.json"
        write_text_atomic(profile, json.dumps(cfg.profile(factors), sort_keys=True))
        req = CollectRequest(cfg.scenario, cfg.robots, cfg.minutes, cfg.seed, folder,
                             "passive", workers=cfg.workers,
                             episode_minutes=cfg.episode_minutes, randomize=str(profile))
        if not finished(req):
            collect(req)
        rows = motion_stats.compare(_features(folder / "instances.csv"), real)
        return {"score.json": json.dumps({"factors": factors, "score": score(rows)}).encode()}

    key = task_key("sysid-score", SCORE_VERSION, made_of, [real_poses])
    scored = json.loads((cache.cached("sysid-score", key, compute) / "score.json").read_text())
    # the folder as named in this run (a score cached by a run elsewhere, copied or moved,
    # may name that run's)
    return scored | {"folder": str(folder), "parked": parked_check(factors, out, cfg)}


def parked_check(factors: dict[str, float], out: Path, cfg: SysidConfig) -> dict:
    """Does the candidate's lab park its chain still (`chain.parked`: teams of 3 and 5)?
    Cached by the factors and the scenario, like the candidate's collection."""
    from macrostate_mj.chain.parked import parks_still

    made_of = {"factors": factors, "scenario": identity(cfg)["scenario_hash"]}

    def compute() -> dict[str, bytes]:
        result = parks_still(randomized_scenario(cfg.scenario, factors))
        return {"parked.json": json.dumps(result, sort_keys=True).encode()}

    key = task_key("sysid-parked", PARKED_VERSION, made_of)
    cache = TaskCache(out / "cache")
    return json.loads((cache.cached("sysid-parked", key, compute) / "parked.json").read_text())


def best_still(tried: list[dict]) -> dict:
    """The best-scoring candidate whose parked chain stands still; one line if none does."""
    still = [c for c in tried if c["parked"]["still"]]
    if not still:
        raise UserError(f"sysid: none of {len(tried)} candidates parks its chain still (the "
                        "scenario's own values among them); check the scenario's gains")
    return min(still, key=lambda c: c["score"])


def real_poses(path: Path, robots: int) -> np.ndarray:
    """A real ThymioLoc file's poses (px, degrees); refused unless `robots` robots, 26 steps."""
    poses = read_csv(path).poses
    motion_stats.check_comparable((0, INSTANCE_STEPS, robots), poses.shape,
                                  (f"a {robots}-robot collection", path.name))
    return poses


def _features(path: Path) -> dict:
    """Motion features of a ThymioLoc file (a candidate's collection)."""
    return motion_stats.features(read_csv(path).poses, DEFAULT_PX_PER_CM)


def fit(cfg: SysidConfig, train: np.ndarray, val: np.ndarray, out: Path,
        progress: Callable[[int, int], None] | None = None) -> dict:
    """Both stages on the real `train` poses (px, degrees: a Train file, or the blocks of a
    cross-validation fold), then the check on `val`; the report (`write` saves it). Candidates
    are cached under `out`, shared by fits against other real data."""
    real = motion_stats.features(train, DEFAULT_PX_PER_CM)
    held = motion_stats.features(val, DEFAULT_PX_PER_CM)
    total, tried = cfg.first + cfg.refine, []

    def run(points: np.ndarray) -> None:
        for x in points:
            factors = feasible(values(x, cfg.fitted), cfg.scenario)
            tried.append(evaluate(factors, out, cfg, real, train))
            if progress is not None:
                progress(len(tried), total)

    run(candidates(cfg))
    run(candidates(cfg, point(best_still(tried)["factors"], cfg.fitted)))
    best = best_still(tried)
    before = tried[0]
    report = {"config": identity(cfg), "fitted": best["factors"],
              "profile": cfg.profile(best["factors"]), "candidates": tried,
              "train": {"before": before["score"], "after": best["score"]}, "val": {},
              "rows": {}}
    for name, cand in (("before", before), ("after", best)):
        sim = _features(Path(cand["folder"]) / "instances.csv")
        val_rows = motion_stats.compare(sim, held)
        report["val"][name] = score(val_rows)
        report["rows"][name] = {"train": motion_stats.compare(sim, real), "val": val_rows}
    return report


def write(report: dict, out: Path) -> None:
    """fit.json (the whole report), fitted.json (the best candidate's collection profile: its
    factors, within the `base` ranges where given; what `--randomize` reads) and the ranked
    gap on the check data before and after (`check_before.jsonl`, `check_after.jsonl`: the
    rows of `stats --compare --rank --json`)."""
    write_json_atomic(out / "fit.json", report)
    write_text_atomic(out / "fitted.json",
                      json.dumps(report["profile"], indent=1, sort_keys=True))
    for name, rows in report["rows"].items():
        write_text_atomic(out / f"check_{name}.jsonl", "".join(
            json.dumps(r, sort_keys=True) + "\n" for r in ranked_gap(rows["val"])))


def split_check(poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A real file's instances cut in two: the fit's, and the last `CHECK_SHARE` it is
    checked on (what a fit does without a check file, leaving every other file unread)."""
    n_check = max(1, int(round(CHECK_SHARE * len(poses))))
    if len(poses) - n_check < 1:
        raise UserError(f"a real file of {len(poses)} instances is too short to keep "
                        f"{CHECK_SHARE:.0%} of it for the check; give --val")
    return poses[:-n_check], poses[-n_check:]


def sysid(cfg: SysidConfig, train: Path, val: Path | None, out: Path, overwrite: bool = False,
          progress: Callable[[int, int], None] | None = None) -> dict:
    """`macrostate-mj sysid` as one call: the real files checked (before the folder is
    touched), the fit under its run in `out` (candidates cached there), fit.json and
    fitted.json written; the report. Without `val`, the fit leaves Train's last
    `CHECK_SHARE` out and is checked on it."""
    from macrostate_mj.core.run import Run

    made_of = {**identity(cfg), "train": str(train), "val": str(val)}
    real = real_poses(train, cfg.robots), real_poses(val, cfg.robots) if val else None
    real = split_check(real[0]) if real[1] is None else real
    with Run(out, "sysid", made_of, cfg.seed, ["fit.json", "fitted.json"], overwrite) as run:
        with run.stage("fit"):
            report = fit(cfg, *real, out, progress)
            write(report, out)
        run.record(workers=cfg.workers)
    return report


# Its tables as the docs show them ------------------------------------------------------------

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
