"""`experiment caging`: four Tails on `macrostate_mj/CagingTail-v0` (seed §2.5.4), through the
Gymnasium API only.

- passive: follows its neighbour (offset 0); the text says this team cannot cage;
- retlo: runs the §2.5 three-MLP ReTLo estimator live at 1 Hz (`OnlineChain`, trained here on
  the robotarium training runs of `experiment retlo-sim` and on rehearsal caging runs, cached)
  from its own and its neighbour's observed positions and the poses the team shares (at τ and
  every 5 s); when its last `TRACK_STEPS` estimates of the Head fit a circle of about the
  boundary's size (`chain.caging.circling_centre`, loose `DETECTION` bounds), it encircles
  clockwise, against the Head: around the mean centre of the circles found, then, once its own
  sensor has the object (the `object` observation), around the object;
- oracle: the same Tail fed the Head's true position each second (privileged): the upper bound;
- random: a new uniform offset within the action bounds every second.
Per policy over the seeds: success rate (caged before the time limit), time to cage, the final
spacing's coefficient of variation (mean ± std), and Fig 2.3-style snapshots of the first seed.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from macrostate_mj.core.io import check_writable_dir, write_json_atomic, write_manifest

POLICIES = ("passive", "retlo", "oracle", "random")
PRODUCTS = ["results.json", "snapshots.png", "oracle_seed0.mp4", "retlo_seed0.mp4",
            "retlo_seed0.rrd", "manifest.json"]
TRACK_STEPS = 5        # how many of the Head's latest positions the Tail fits a circle to
DETECTION = {"min_arc_deg": 90.0, "max_rms": 0.06, "radius_factor": 2.0}   # loose: estimates


@dataclass(frozen=True)
class CagingExperiment:
    seeds: int = 20
    time_limit: float = 90.0
    epochs: int = 200          # the three MLPs (retlo-sim trains 500; 200 converge here)
    train_steps: int = 800
    rehearsals: int = 40       # passive-Tail caging runs the estimator also learns from
    stride: int = 30           # the estimator's step in command ticks: 1 Hz (see the README)
    seed: int = 0


class _Tail:
    """A scripted Tail: watch the Head's track (one position per estimator step); once it
    circles, encircle clockwise: around the mean centre of every circle found so far (an estimated
    track gives a new, noisy fit at most steps) until its own sensor finds the object, then
    around the object it senses (and remembers)."""

    def __init__(self, env, head_source: Callable[[dict, dict], np.ndarray | None]):
        from macrostate_mj.chain.caging import CagingConfig

        task = env.unwrapped._task
        self.sim_cfg, self.k_t = task.sim.cfg, task.sim.k_t
        self.caging: CagingConfig = task.caging
        self.bound = float(env.action_space.high[0])
        self.head_source = head_source
        self.track: list[np.ndarray] = []
        self.found: list[np.ndarray] = []          # the centres of the circles found
        self.sensed: np.ndarray | None = None      # the object's centre, once sensed
        self.detected_at: float | None = None

    @property
    def centre(self) -> np.ndarray | None:
        """Where the Tail encircles: the sensed object, else the circles' mean centre."""
        if self.sensed is not None or not self.found:
            return self.sensed
        return np.mean(self.found, axis=0)

    def act(self, obs: dict, info: dict, t: float) -> np.ndarray:
        from macrostate_mj.chain.caging import (
            circle_velocity,
            circling_centre,
            offset_for_velocity,
        )

        head = self.head_source(obs, info)
        if head is not None:
            self.track = [*self.track[-(TRACK_STEPS - 1):], head]
            found = (circling_centre(np.array(self.track), self.caging, **DETECTION)
                     if len(self.track) == TRACK_STEPS and self.sensed is None else None)
            if found is not None:
                self.found.append(found)
                self.detected_at = self.detected_at or t
        tail, fol = obs["tail"][-1], obs["neighbour"][-1]
        if self.found and obs["object"][2] > 0:
            self.sensed = tail[:2] + obs["object"][:2]
        if self.centre is None:
            return np.zeros(2, np.float32)
        u = circle_velocity(tail[:2], self.centre, self.caging.ring_radius,
                            self.sim_cfg.chain_speed, -1.0, self.caging.circle_gain)
        w = offset_for_velocity(u, tail, fol, self.sim_cfg.spacing, self.k_t, self.bound)
        return w.astype(np.float32)


def _oracle_source(sim, stride: int) -> Callable[[dict, dict], np.ndarray | None]:
    """The Head's true position every `stride` ticks (privileged, no lag)."""
    ticks = [-1]

    def source(_obs: dict, _info: dict) -> np.ndarray | None:
        ticks[0] += 1
        return sim.poses[0, :2].copy() if ticks[0] % stride == 0 else None
    return source


def _retlo_source(model, env, info: dict, seconds: float, stride: int
                  ) -> Callable[[dict, dict], np.ndarray | None]:
    """The Head's position as the Tail's live ReTLo estimator has it after each of its steps
    (lagging n - 2 steps), from its observations and the poses the team shares (at τ and every
    `share_every_s`); None between steps."""
    from estimators.retlo_sim.estimate import OnlineChain

    sim = env.unwrapped._task.sim
    chain = OnlineChain(model.predict, sim.n, int(seconds * sim.cfg.command_hz / stride) + 2)
    chain.start(info["team_at_start"][::-1])            # Tail first
    ticks = [-1]          # the observation of tick k comes with the info of tick k

    def source(obs: dict, step_info: dict) -> np.ndarray | None:
        ticks[0] += 1
        if ticks[0] == 0 or ticks[0] % stride:
            return None
        chain.observe(np.array([obs["tail"][-1, :2], obs["neighbour"][-1, :2]]))
        if "team" in step_info:
            chain.share(step_info["team"][::-1])
        t, head = chain.head
        return head.copy() if t > 0 else None
    source.estimate = lambda: (chain.head[0] * stride, chain.head[1])   # (tick, Head)
    return source


def run_episode(policy: str, seed: int, cfg: CagingExperiment, model=None,
                frames_every: float | None = None, video: Path | None = None,
                rerun: Path | None = None) -> dict:
    """One seeded episode of one Tail; its outcome (and snapshots, a video with the object and
    the Tail's estimate of the Head drawn in, a rerun recording, when asked)."""
    import gymnasium

    import macrostate_mj.env  # noqa: F401  (registers the ids)
    from macrostate_mj.chain.caging import cage_report

    env = gymnasium.make("macrostate_mj/CagingTail-v0", time_limit=cfg.time_limit)
    obs, info = env.reset(seed=seed)
    sim = env.unwrapped._task.sim
    tail, source = None, None
    if policy == "retlo":
        source = _retlo_source(model, env, info, cfg.time_limit, cfg.stride)
        tail = _Tail(env, source)
    elif policy == "oracle":
        tail = _Tail(env, _oracle_source(sim, cfg.stride))
    recorders = _recorders(sim, env.unwrapped._task.caging, video, rerun,
                           lambda: None if tail is None or not tail.track else tail.track[-1])
    rng = np.random.default_rng([cfg.seed, seed, 7])
    action = np.zeros(2, np.float32)
    frames, next_frame, done = [], 0.0, False
    estimate = None
    per_second = int(round(sim.cfg.command_hz))
    heads, errors = [], []            # the Head's true track, the ReTLo estimate's errors
    tick = 0
    while not done:
        t = sim.time
        if frames_every is not None and t >= next_frame - 1e-9:
            frames.append({"t": t, "poses": sim.poses.copy(), "head_estimate":
                           None if estimate is None else estimate.copy()})
            next_frame += frames_every
        heads.append(sim.poses[0, :2].copy())
        if tail is not None:
            action = tail.act(obs, info, t)
            estimate = tail.track[-1] if tail.track else None
        if source is not None and estimate is not None:
            at, head = source.estimate()
            errors.append(float(np.linalg.norm(head - heads[at])))
        if policy == "random" and tick % per_second == 0:       # a new offset each second
            action = rng.uniform(-1, 1, 2).astype(np.float32) * env.action_space.high
        for every, recorder in recorders:
            if tick % every == 0:
                recorder.capture(sim)
                if hasattr(recorder, "log_points") and estimate is not None:
                    recorder.log_points("head_estimate", estimate, 0.012, (230, 60, 60),
                                        "Tail's estimate of H")
        obs, _, terminated, truncated, info = env.step(action)
        done = terminated or truncated
        tick += 1
    report = cage_report(sim.poses, env.unwrapped._task.caging)
    out = {"policy": policy, "seed": seed, "caged": info["caged_at"] is not None,
           "time_to_cage_s": info["caged_at"], "spacing_cv": report["spacing_cv"],
           "detected_at_s": None if tail is None else tail.detected_at,
           "head_estimate_error_m": float(np.mean(errors)) if errors else None,
           "fault": info["fault"]}
    if frames_every is not None:
        frames.append({"t": sim.time, "poses": sim.poses.copy(), "head_estimate": estimate})
        out["frames"] = frames
    for _, recorder in recorders:
        recorder.finish()
    env.close()
    return out


def _recorders(sim, caging, video: Path | None, rerun: Path | None,
               estimate: Callable[[], np.ndarray | None]) -> list[tuple[int, object]]:
    """(every how many ticks, recorder): a 10 fps video with the object, the boundary and the
    Tail's estimate of the Head drawn in, and a 10 Hz rerun recording with the estimate."""
    import cv2

    out: list[tuple[int, object]] = []
    every = max(1, int(round(sim.cfg.command_hz / 10)))
    if video is not None:
        from viz.video import VideoRecorder

        def decorate(bgr: np.ndarray, px) -> None:
            c = px(np.array(caging.centre))[0]
            scale = np.linalg.norm(px(np.array(caging.centre) + [1.0, 0.0])[0] - c)
            centre = tuple(int(v) for v in np.round(c))
            cv2.circle(bgr, centre, int(caging.object_radius * scale), (150, 150, 150), -1)
            cv2.circle(bgr, centre, int(caging.ring_radius * scale), (60, 60, 60), 1,
                       cv2.LINE_AA)
            head = estimate()
            if head is not None:
                u, v = np.round(px(head)[0]).astype(int)
                cv2.circle(bgr, (int(u), int(v)), 9, (60, 60, 230), 2, cv2.LINE_AA)
                cv2.putText(bgr, "Tail's estimate of H", (int(u) + 11, int(v) - 6),
                            cv2.FONT_HERSHEY_SIMPLEX, 0.4, (60, 60, 230), 1, cv2.LINE_AA)
        out.append((every, VideoRecorder(video, sim, fps=10.0, decorate=decorate)))
    if rerun is not None:
        from viz.rerun_log import RerunRecorder

        recorder = RerunRecorder(rerun, sim, rate_hz=10.0)
        recorder.log_points("object", np.array(caging.centre), caging.object_radius,
                            (150, 150, 150), "object", static=True)
        out.append((every, recorder))
    return out


def rehearsal_runs(runs: int, seconds: float) -> np.ndarray:
    """Caging episodes with a passive Tail (seeds 10000.., never an evaluation seed), every
    consecutive three robots as a 3-robot module run: (runs * (n - 2), steps, 3, 3), H first."""
    from macrostate_mj.chain.caging import CagingConfig, CagingMission, start_poses
    from macrostate_mj.chain.scenarios import get_scenario
    from macrostate_mj.chain.sim import ChainSim, Every
    from macrostate_mj.chain.world import build_world

    caging = CagingConfig()
    world = build_world(get_scenario("robotarium"), 6)
    sim = ChainSim(world, mission=CagingMission(caging))
    out = []
    for i in range(runs):
        rng = np.random.default_rng(10_000 + i)
        sim.reset(rng, start=start_poses(caging, sim.n, sim.cfg.spacing, rng))
        log: list[np.ndarray] = []
        sim.run(seconds, [Every(1 / sim.cfg.log_hz, lambda s, log=log: log.append(s.poses))])
        poses = np.array(log)
        out += [poses[:, k:k + 3] for k in range(sim.n - 2)]
    return np.array(out)


def _train_model(cfg: CagingExperiment, path: Path):
    """The three MLPs of §2.5 on the robotarium training runs of `experiment retlo-sim` and on
    rehearsal caging runs with a passive Tail (cached as .npz)."""
    from collectors.robotarium import K_T_FACTORS, noisy_replicas, training_runs
    from estimators.retlo_sim.frames import training_pairs
    from estimators.retlo_sim.mlp import ChainedMLP, train_mlp
    from macrostate_mj.chain.scenarios import get_scenario

    if path.exists():
        with np.load(path) as z:
            return ChainedMLP(**{k: z[k] for k in z.files})
    rng = np.random.default_rng(cfg.seed)
    runs = training_runs(get_scenario("robotarium"), cfg.train_steps, K_T_FACTORS)
    rehearsed = rehearsal_runs(cfg.rehearsals, cfg.time_limit)
    parts = [training_pairs(noisy_replicas(r[:, k::cfg.stride], 5, 0.001, rng))
             for r in (runs, rehearsed) for k in range(cfg.stride)]
    base, targets = (np.concatenate(a) for a in zip(*parts, strict=True))
    model, _ = train_mlp(base, targets, rng, cfg.epochs, 0.05, 0.2, 128)
    np.savez(path, **asdict(model))
    return model


def run_caging(cfg: CagingExperiment, out: Path) -> list[str]:
    """Every policy on every seed; results.json, snapshots.png, manifest; summary lines."""
    from macrostate_mj.chain.caging import CagingConfig
    from macrostate_mj.core.progress import LoggedProgress
    from viz.caging_figures import plot_snapshots

    t0 = time.perf_counter()
    models = check_writable_dir(out / "models")
    model = _train_model(cfg, models / f"retlo_mlp_stride{cfg.stride}.npz")
    timings = {"train_retlo": time.perf_counter() - t0}
    episodes, snapshots = [], {}
    with LoggedProgress(transient=True) as bar:
        task = bar.add_task("experiment caging", total=len(POLICIES) * cfg.seeds)
        for policy in POLICIES:
            t1 = time.perf_counter()
            for seed in range(cfg.seeds):
                first = seed == 0 and policy in ("oracle", "retlo")
                ep = run_episode(policy, seed, cfg, model, 5.0 if seed == 0 else None,
                                 out / f"{policy}_seed0.mp4" if first else None,
                                 out / "retlo_seed0.rrd" if first and policy == "retlo"
                                 else None)
                if "frames" in ep:
                    snapshots[policy] = ep.pop("frames")
                episodes.append(ep)
                bar.advance(task)
            timings[f"episodes_{policy}"] = time.perf_counter() - t1
    table = {p: _summary([e for e in episodes if e["policy"] == p]) for p in POLICIES}
    oracle = table["oracle"]["success_rate"]
    results = {"config": asdict(cfg), "caging": asdict(CagingConfig()), "table": table,
               "retlo_over_oracle": table["retlo"]["success_rate"] / oracle if oracle else None,
               "episodes": episodes}
    write_json_atomic(out / "results.json", results)
    picked = [dict(f, label=p) for p in ("oracle", "retlo", "passive")
              for f in snapshots[p][1:5]]
    plot_snapshots(picked, CagingConfig(), (1.2, 0.7), out / "snapshots.png",
                   "seed 0, every 5 s: oracle Tail (top), ReTLo Tail (middle; circle: its "
                   "estimate of the Head), passive Tail (bottom)", zoom=0.25)
    write_manifest(out, "experiment caging", asdict(cfg), cfg.seed, timings,
                   products=PRODUCTS)
    return [f"{p:<8} caged {t['success_rate'] * 100:.0f} % of {t['seeds']} seeds, time "
            f"{_fmt(t['time_to_cage_s'])} s, spacing CV {_fmt(t['spacing_cv'], 3)}"
            for p, t in table.items()]


def _summary(eps: list[dict]) -> dict:
    caged = [e for e in eps if e["caged"]]

    def stat(values: list[float]) -> dict:
        return ({"mean": float(np.mean(values)), "std": float(np.std(values))} if values
                else {"mean": None, "std": None})
    return {"seeds": len(eps), "success_rate": len(caged) / len(eps),
            "time_to_cage_s": stat([e["time_to_cage_s"] for e in caged]),
            "spacing_cv": stat([e["spacing_cv"] for e in caged]),
            "faults": sum(e["fault"] is not None for e in eps),
            "head_estimate_error_m": stat([e["head_estimate_error_m"] for e in eps
                                           if e["head_estimate_error_m"] is not None])}


def _fmt(s: dict, digits: int = 1) -> str:
    return "-" if s["mean"] is None else f"{s['mean']:.{digits}f} ± {s['std']:.{digits}f}"
