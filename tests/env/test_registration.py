"""`import macrostate_mj` registers the Tail's Gymnasium ids, cheaply, and gymnasium's
"macrostate_mj:<id>" form works in a fresh interpreter (as in a vector env's spawned worker)."""

import subprocess
import sys

from macrostate_mj.gym_ids import ENVS


def _fresh(code: str) -> str:
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120)
    assert run.returncode == 0, run.stderr
    return run.stdout.strip()


def test_module_colon_id_makes_the_env_with_no_prior_import():
    out = _fresh(
        "import sys, gymnasium\n"
        "assert 'macrostate_mj' not in sys.modules\n"
        "env = gymnasium.make('macrostate_mj:macrostate_mj/ExploreTail-v0', robots=3)\n"
        "obs, info = env.reset(seed=0)\n"
        "print(env.unwrapped.task.__class__.__name__, obs['tail'].shape)\n"
        "env.close()")
    assert out == "ExploreTask (10, 3)", out


def test_importing_the_package_registers_every_id_without_the_env_modules():
    out = _fresh(
        "import sys, macrostate_mj, gymnasium\n"
        f"assert all(i in gymnasium.registry for i in {list(ENVS)!r})\n"
        "print(gymnasium.spec('macrostate_mj/CagingTail-v0').kwargs['robots'],\n"
        "      sorted(m for m in ('macrostate_mj.env', 'dm_control', 'mujoco', 'torch')\n"
        "             if m in sys.modules))")
    assert out == "6 []", out


def test_the_package_imports_without_gymnasium():
    out = _fresh("import sys\nsys.modules['gymnasium'] = None\n"
                 "import macrostate_mj\nprint(macrostate_mj.gym_ids.register())")
    assert out == "False", out
