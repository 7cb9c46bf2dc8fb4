"""MuJoCo's interactive viewer on a running chain (`macrostate-mj view`).

The same world and controllers as `simulate` (planner, motion rules, unicycle tracking), paced
to real time (or `speed` times it) while the window is open. The viewer needs a display: on a
headless machine the command says so in one line, and `simulate --video` is the way to look.
"""

from __future__ import annotations

import os
import time

import numpy as np

from macrostate_mj.chain.scenario import ScenarioConfig
from macrostate_mj.chain.sim import ChainSim
from macrostate_mj.chain.world import build_world, validate_chain
from macrostate_mj.core.errors import UserError


def check_display() -> None:
    if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        raise UserError("no display: `view` opens a window (run it on a desktop, or under "
                        "`xvfb-run`); headless, use `simulate --video run.mp4`")


def view(cfg: ScenarioConfig, robots: int, seed: int, seconds: float | None = None,
         speed: float = 1.0) -> float:
    """Run the chain in the viewer until the window closes (or `seconds` pass); returns the
    simulated time reached."""
    validate_chain(cfg, robots, seconds or 1.0)
    check_display()
    import mujoco.viewer

    sim = ChainSim(build_world(cfg, robots))
    sim.reset(np.random.default_rng(seed))
    tick = 1 / cfg.command_hz
    _check_glfw()
    handle = mujoco.viewer.launch_passive(sim.model, sim.data)
    try:
        wall0, sim0 = time.monotonic(), sim.time
        while handle.is_running() and (seconds is None or sim.time < sim0 + seconds - 1e-9):
            with handle.lock():
                sim.run(tick, hooks=[])
            handle.sync()
            ahead = (sim.time - sim0) / speed - (time.monotonic() - wall0)
            if ahead > 0:
                time.sleep(ahead)
    finally:
        _close(handle)
    return sim.time


def _check_glfw() -> None:
    """GLFW must open the display; otherwise the viewer prints its own error and exits."""
    import warnings

    import glfw

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ok = glfw.init()
    if not ok:
        raise UserError(f"cannot open a window on display {os.environ.get('DISPLAY', '')!r} "
                        "(no X server there?); headless, use `simulate --video run.mp4`")


def _close(handle: object, timeout: float = 5.0) -> None:
    """Close the window and wait for the viewer's thread to let go of it: exiting while it
    still holds its GL context crashes in GLFW (mujoco issue #790)."""
    handle.close()
    deadline = time.monotonic() + timeout
    while handle.is_running() and time.monotonic() < deadline:
        time.sleep(0.05)
    time.sleep(0.2)
