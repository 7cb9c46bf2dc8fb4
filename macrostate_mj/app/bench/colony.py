"""Speed of the simulated colony: our behaviour + control loop against bare `mj_step` replaying
the same actuator commands from the same state, the overhead render, and the whole day pipeline
(physics, the frames the flow samples need, DIS flows) in simulated seconds per wall second."""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from macrostate_mj.app.bench import SUITES, figure
from macrostate_mj.app.bench.sim import _best_of
from macrostate_mj.colony.colony_sim import Colony, ColonyConfig


@SUITES.register("colony", rank=70)
def bench_colony(ants: int = 55, seconds: float = 4.0, size: int = 256) -> list[dict]:
    import mujoco

    from macrostate_mj.vision.flow import extract_flow_samples, sample_frame_indices

    colony = Colony(ColonyConfig(n_ants=ants, size=size, warmup_s=0.5))
    model, fps = colony.model, colony.cfg.fps
    frames = int(round(seconds * fps))
    steps = frames * colony.steps_per_frame
    commands: list[np.ndarray] = []  # ctrl at each controller tick

    colony.reset(1)
    start = colony.data.qpos.copy()

    def ours() -> None:
        colony.reset(1)
        for _ in range(frames):
            colony.advance_frame()

    colony.reset(1)
    for _ in range(frames):  # one recording pass: the controls our loop applies at each step
        colony.advance_frame(commands)
    data = mujoco.MjData(model)

    def bare() -> None:
        mujoco.mj_resetData(model, data)
        data.qpos[:] = start
        for ctrl in commands:
            data.ctrl[:] = ctrl
            mujoco.mj_step(model, data)

    t_ours, t_bare = _best_of(ours, 2), _best_of(bare, 2)
    renderer = mujoco.Renderer(model, size, size)
    try:
        t_render = _best_of(lambda: [(renderer.update_scene(colony.data, camera="overhead"),
                                      renderer.render()) for _ in range(30)], 2) / 30
        needed = {f for s in range(int(seconds // 2))
                  for f in sample_frame_indices(s, fps, 2.0, 0.5, 4)}
        colony.reset(1)
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            stream = (f for f, _ in colony.run(seconds, needed, renderer))
            last: list[np.ndarray] = []

            def fill():  # unrendered frames repeat the last one, as in collectors.colony_days
                for f in stream:
                    if f is not None:
                        last[:] = [f]
                    yield last[0]

            extract_flow_samples(fill(), fps, Path(tmp), every=2.0, label="Unstable")
            t_day = time.perf_counter() - t0
    finally:
        renderer.close()
    tag = f"{ants} ants, dt={model.opt.timestep:.4f}, D+1"
    return [
        figure("colony_steps_per_s", steps / t_ours, "steps/s", steps / t_bare,
               limit_name="bare mj_step replaying the same controls", config=tag),
        figure("colony_render_fps", 1 / t_render, "frames/s", config=f"{size}x{size}, {tag}"),
        figure("colony_pipeline_realtime", seconds / t_day, "sim s per wall s",
               config=f"{size}x{size}, 15 fps, samples every 2 s, m=4, DIS, {tag}"),
    ]
