"""Every MJCF we ship, as MuJoCo Menagerie's model_test steps every model: it compiles, steps
2,000 physics steps and raises no MuJoCo warning; so does every built-in scenario's generated
scene, alone and with a chain of robots."""

from pathlib import Path

import mujoco
import numpy as np
import pytest

from macrostate_mj.chain.scenarios import SCENARIOS
from macrostate_mj.chain.scene import build_scene
from macrostate_mj.chain.sim import ChainSim
from macrostate_mj.chain.world import build_world
from macrostate_mj.core.paths import ASSETS

FILES = sorted(p.relative_to(ASSETS) for p in ASSETS.rglob("*.xml"))


def step(model: mujoco.MjModel, data: mujoco.MjData, steps: int = 2000) -> dict[int, int]:
    """Step, then MuJoCo's warning counters that fired (by mjtWarning index)."""
    mujoco.mj_step(model, data, nstep=steps)
    return {i: data.warning[i].number for i in range(len(data.warning)) if data.warning[i].number}


def finite(data: mujoco.MjData) -> bool:
    return bool(np.all(np.isfinite(data.qpos)) and np.all(np.isfinite(data.qvel)))


@pytest.mark.parametrize("path", FILES, ids=str)
def test_file_compiles_and_steps_without_warnings(path: Path):
    model = mujoco.MjModel.from_xml_path(str(ASSETS / path))
    data = mujoco.MjData(model)
    assert step(model, data) == {}
    assert finite(data)


@pytest.mark.parametrize("scenario", sorted(SCENARIOS))
def test_generated_scene_steps_without_warnings(scenario):
    cfg = SCENARIOS[scenario]
    model = build_scene(cfg.name, cfg.arena, cfg.walls, cfg.camera, cfg.look, cfg.physics).compile()
    data = mujoco.MjData(model)
    assert step(model, data) == {}
    assert finite(data)


@pytest.mark.parametrize("scenario", sorted(SCENARIOS))
def test_scene_with_a_chain_steps_without_warnings_while_driving(scenario):
    world = build_world(SCENARIOS[scenario], 4)
    sim = ChainSim(world)
    sim.reset(np.random.default_rng(0))
    sim.command()                      # wheels turning, so contacts and actuators are exercised
    assert step(world.model, sim.data) == {}
    assert finite(sim.data) and sim.monitor.check(sim.data) is None
