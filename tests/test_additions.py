"""What a newcomer writes to add a scenario, a robot, a Tail or an estimator, held by count: each
test writes a toy one into a temporary folder (never the repository), uses it by name or path
as a user would, and counts the files it needed, so that the design page's counts
(docs/explanation/design.md) stay true. An experiment's count is tests/app/test_new_experiment.py's.

Code entries (a Tail, a ReTLo model kind, a one-class method) go into a temporary package that
the registry scans only inside the test (`Registry.scanning`), standing in for the line that
registers them in the package (POLICIES, MODEL_KINDS and METHODS scan no package: an entry of
the package is registered in, or imported by, the registry's own module).
"""

from __future__ import annotations

import contextlib
import sys
import textwrap
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from clitools import cli_inprocess

from macrostate_mj.chain.robot import ASSETS, ROBOT_FILE
from macrostate_mj.chain.scenarios import get_scenario
from macrostate_mj.core.errors import UserError
from macrostate_mj.core.registry import Registry


def written(root: Path) -> list[str]:
    """The files under `root` (bytecode caches aside): what the newcomer wrote."""
    return sorted(p.relative_to(root).as_posix() for p in root.rglob("*")
                  if p.is_file() and "__pycache__" not in p.parts)


@pytest.fixture
def toy_package(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator:
    """`add(registry, package, module, source)`: one module in a temporary namespace package
    on the path, scanned by `registry` until the test ends; its entries and modules are gone
    after it."""
    root = tmp_path / "code"
    root.mkdir()
    monkeypatch.syspath_prepend(str(root))
    added: list[tuple[Registry, str, set[str]]] = []

    with contextlib.ExitStack() as scans:
        def add(registry: Registry, package: str, module: str, source: str) -> Path:
            (root / package).mkdir()
            (root / package / f"{module}.py").write_text(textwrap.dedent(source))
            added.append((registry, package, set(registry.names())))
            scans.enter_context(registry.scanning(package))
            return root

        yield add
    for registry, package, before in added:
        for name in [m for m in sys.modules if m == package or m.startswith(f"{package}.")]:
            del sys.modules[name]
        assert set(registry.names()) == before        # nothing left to the tests after this


def test_a_scenario_is_one_user_file(tmp_path, capsys):
    """A lab of one's own: one TOML file extending a built-in, passed by path wherever a
    scenario is named (`--scenario PATH`, `ScenarioRef`). A built-in, usable by bare name, is
    the same file in macrostate_mj/assets/scenarios/ (plus its golden scene for test_scene)."""
    mine = tmp_path / "user"
    mine.mkdir()
    path = mine / "mylab.toml"
    path.write_text('extends = "lab"\nname = "mylab"\n\n[chain]\nspacing = 0.25\n'
                    'head_speed = 0.06\n')
    assert written(mine) == ["mylab.toml"]

    cfg, lab = get_scenario(path), get_scenario("lab")
    assert get_scenario(str(path)) == cfg
    assert (cfg.name, cfg.spacing, cfg.head_speed) == ("mylab", 0.25, 0.06)
    assert (cfg.robot, cfg.arena, cfg.camera) == (lab.robot, lab.arena, lab.camera)  # inherited
    code, out, err = cli_inprocess(capsys, "scenario", "check", str(path))
    assert code == 0, err
    assert out.startswith("scenario   mylab: robot thymio") and "Head 0.06 m/s" in out, out
    with pytest.raises(UserError, match="unknown scenario 'mylab'"):
        get_scenario("mylab")                 # by bare name only from the package's folder


TOP_SPEED = 8.0 * 0.0215        # the toy's motors: 8 rad/s on Thymio's 21.5 mm wheels


def test_a_robot_is_one_folder_with_robot_xml_named_by_a_scenario_file(tmp_path, capsys):
    """A robot of one's own: `<folder>/robot.xml` (meshes inline, or beside it when the file
    names mesh files), usable through a scenario file whose `robot.model` is its path (relative
    to the scenario file): 2 files. By bare name a robot comes only from the package's
    macrostate_mj/assets/mjcf/<name>/robot.xml (1 file there)."""
    mine = tmp_path / "user"
    folder = mine / "toybot"
    folder.mkdir(parents=True)
    thymio = (ASSETS / "thymio" / ROBOT_FILE).read_text()
    assert thymio.count('ctrlrange="-9.3 9.3"') == 1
    (folder / ROBOT_FILE).write_text(thymio.replace('ctrlrange="-9.3 9.3"', 'ctrlrange="-8 8"'))
    scenario = mine / "toylab.toml"
    scenario.write_text('extends = "lab"\nname = "toylab"\n\n[robot]\nmodel = "./toybot"\n')
    assert written(mine) == ["toybot/robot.xml", "toylab.toml"]

    cfg = get_scenario(scenario)
    assert Path(cfg.robot).resolve() == folder.resolve()     # anchored at the scenario file
    code, out, err = cli_inprocess(capsys, "scenario", "check", str(scenario))
    assert code == 0, err
    assert f"(robot's top {TOP_SPEED:.3f} m/s)" in out, out  # the toy's motors, not Thymio's
    with pytest.raises(UserError, match="unknown robot 'toybot'"):
        get_scenario("lab").with_overrides(robot="toybot")   # not a shipped robot's name


CIRCLE = '''
    """A toy Tail: its destination moved a fixed distance, turning with time."""

    import numpy as np

    from macrostate_mj.chain.motion import ROBOT_SIZE_M
    from macrostate_mj.tails.collection import POLICIES, PolicyConfig

    ACTED: list[float] = []        # the times it acted at (read by the test)


    class Circle:
        def __init__(self, radius: float) -> None:
            self.radius = radius

        def act(self, obs: dict, info: dict) -> np.ndarray:
            ACTED.append(info["t"])
            return self.radius * np.array([np.cos(info["t"]), np.sin(info["t"])])


    @POLICIES.register("circle")
    def _circle(rng: np.random.Generator, cfg: PolicyConfig) -> Circle:
        return Circle(cfg.sigma * ROBOT_SIZE_M)
'''


def test_a_tail_is_one_module_registered_in_policies(toy_package):
    """A Tail a collection picks by name: one module with a class that has `act` (the `Tail`
    protocol) and a factory registered in POLICIES. In the package the registration must sit
    in, or be imported by, tails/collection.py (POLICIES scans no package; `collect --policy`
    lists its choices when the CLI loads, and spawned workers rebuild the Tail by name)."""
    from collectors.episodes import EpisodeSpec, run_episode
    from macrostate_mj.tails.collection import POLICIES, PolicyConfig

    root = toy_package(POLICIES, "toy_tails", "circle", CIRCLE)
    assert written(root) == ["toy_tails/circle.py"]
    assert "circle" in POLICIES.names()

    def episode(policy: str) -> tuple[dict, list[float]]:
        """One collection episode of 8 s in the lab (simulated, filmed, tracked)."""
        _, table, _ = run_episode(EpisodeSpec(get_scenario("lab"), 3, 8.0, 0.0, 5, 0,
                                              PolicyConfig(policy, sigma=2.0)))
        rows = table.to_pandas()
        return {r: rows[rows.robot == r][["x", "y"]].to_numpy() for r in ("H", "T")}, rows.t

    acted = sys.modules["toy_tails.circle"].ACTED
    passive, _ = episode("passive")
    circled, times = episode("circle")
    assert acted == pytest.approx(sorted(set(times)))        # once per log step
    assert np.array_equal(circled["H"], passive["H"])        # the same episode otherwise
    assert np.abs(circled["T"] - passive["T"]).max() > 0.01  # the Tail went elsewhere


FLAT = '''
    """A toy ReTLo model kind: the observation alone, under a name of its own."""

    from estimators.retlo import MODEL_KINDS, ModelKind

    MODEL_KINDS.register("flat")(ModelKind(history=False))
'''


def test_a_retlo_model_kind_is_one_registered_entry(toy_package):
    """A ReTLo model kind by name: one `ModelKind` entry in MODEL_KINDS (in the package, a
    line of estimators/retlo/__init__.py). A kind chooses only whether `models.RetloNet` reads
    history: another architecture is an edit of RetloNet itself."""
    from estimators.retlo import MODEL_KINDS
    from estimators.retlo.api import evaluate, fit
    from estimators.retlo.models import ModelConfig, TorchPredictor
    from estimators.retlo.synthetic import synthetic_chains
    from estimators.retlo.train import TrainConfig

    root = toy_package(MODEL_KINDS, "toy_kinds", "flat", FLAT)
    assert written(root) == ["toy_kinds/flat.py"]

    cfg = TrainConfig(epochs=1, model=ModelConfig(kind="flat", history=4))
    net, record = fit([synthetic_chains(8, 3, 1, n_steps=14)],
                      synthetic_chains(4, 3, 2, n_steps=14), cfg)
    assert net.cfg.kind == "flat" and not hasattr(net, "f_hist")     # no LSTM: no history
    report = evaluate(TorchPredictor(net), synthetic_chains(4, 3, 3, n_steps=14))
    assert np.isfinite(report["mean_error_cm"])


MEAN_FLOW = '''
    """A toy one-class method: the mean absolute flow, needing no trained stage."""

    import numpy as np

    from estimators.oneclass.methods import method


    @method("meanabs", needs=())
    def _meanabs(model, inputs: np.ndarray) -> np.ndarray:
        return np.abs(inputs).reshape(len(inputs), -1).mean(1)
'''


def test_a_one_class_method_is_one_registered_score(toy_package):
    """A one-class method by name: one score registered with `methods.method` (in the
    package, in estimators/oneclass/methods.py) from the stages that exist; a new stage is an
    edit of `model.fit`, and `experiment oc` also needs its label in viz/oneclass_figures.py."""
    from estimators.oneclass import METHODS, OCConfig, fit

    root = toy_package(METHODS, "toy_methods", "meanabs", MEAN_FLOW)
    assert written(root) == ["toy_methods/meanabs.py"]

    rng = np.random.default_rng(0)
    still = rng.normal(0, 0.01, (6, 2, 64, 64)).astype(np.float32)
    moving = rng.normal(0.2, 0.01, (6, 2, 64, 64)).astype(np.float32)
    model = fit(still, ("meanabs",), OCConfig(m=1))
    assert model.methods == ("meanabs",)
    assert model.score("meanabs", moving).min() > model.score("meanabs", still).max()
