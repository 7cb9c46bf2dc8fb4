"""One registry pattern: entries register by decorator where they are defined, found by scanning
their packages; an unknown name is one line naming the choices."""

import subprocess
import sys

import pytest

from macrostate_mj.core.errors import UserError
from macrostate_mj.core.registry import Registry, scan


def test_entries_register_in_order_and_an_unknown_name_names_the_choices():
    things: Registry[object] = Registry("thing")

    @things.register("b")
    def b() -> None: ...

    things.register("a")(1)
    assert things.names() == ("b", "a") and things["b"] is b and "a" in things
    assert list(things) == ["b", "a"] and len(things) == 2
    with pytest.raises(UserError, match="unknown thing 'c'; choose from b, a"):
        things["c"]
    with pytest.raises(ValueError, match="two things named 'a'"):
        things.register("a")(2)


def test_ranked_entries_read_in_rank_order_whatever_registered_first():
    things: Registry[int] = Registry("thing")
    things.register("late", rank=2)(1)
    things.register("early", rank=1)(2)
    things.register("tie", rank=1)(3)
    assert things.names() == ("early", "tie", "late") and list(things) == list(things.names())
    assert [v for _, v in things.items()] == [2, 3, 1]
    with pytest.raises(UserError, match="choose from early, tie, late"):
        things["none"]


def test_a_registry_imports_its_modules_on_first_read_only():
    code = ("import sys; from macrostate_mj.app.bench import SUITES; "
            "assert 'macrostate_mj.app.bench.srs' not in sys.modules; "
            "assert SUITES.names()[:3] == ('sim', 'render', 'env'); "
            "assert 'macrostate_mj.app.bench.srs' in sys.modules")
    subprocess.run([sys.executable, "-c", code], check=True)


def test_the_bench_runs_its_suites_in_rank_order_whichever_module_is_imported_first():
    code = ("import macrostate_mj.app.bench.srs; from macrostate_mj.app.bench import SUITES; "
            "print(' '.join(SUITES))")
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True,
                         text=True).stdout.split()
    assert out == ["sim", "render", "env", "tracker", "health", "collect", "colony", "retlo",
                   "flow", "iogen", "srs", "ensemble"]


def test_scan_names_a_packages_modules_not_starting_with_an_underscore(tmp_path, monkeypatch):
    package = tmp_path / "scanned_pkg"
    package.mkdir()
    for name in ("__init__", "b", "a", "_private"):
        (package / f"{name}.py").write_text("")
    (package / "sub").mkdir()
    (package / "sub" / "__init__.py").write_text("")
    monkeypatch.syspath_prepend(str(tmp_path))
    assert scan("scanned_pkg") == ["scanned_pkg.a", "scanned_pkg.b", "scanned_pkg.sub"]
    assert "scanned_pkg.a" not in sys.modules
    sys.modules.pop("scanned_pkg")


def test_a_package_scanned_inside_a_block_is_forgotten_after_it(tmp_path, monkeypatch):
    """The toy module registers in this file's `THINGS`, found under the name it imports."""
    package = tmp_path / "toy_things"
    package.mkdir()
    (package / "__init__.py").write_text("")
    (package / "one.py").write_text("from test_registry import THINGS\n"
                                    "THINGS.register('one')(1)\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setitem(sys.modules, "test_registry", sys.modules[__name__])
    THINGS.register("kept")(0)
    with THINGS.scanning("toy_things"):
        assert THINGS.module_names() == ("toy_things.one",) and THINGS.names() == ("kept", "one")
    assert THINGS.names() == ("kept",) and THINGS.module_names() == ()
    for module in ("toy_things.one", "toy_things"):
        sys.modules.pop(module)


THINGS: Registry[int] = Registry("thing")


def test_every_experiment_module_registers_itself():
    from macrostate_mj.app.experiments import EXPERIMENTS, names, registry

    assert list(registry()) == names() and set(EXPERIMENTS) == set(names())


def test_the_cli_imports_every_command_module_of_its_package():
    import macrostate_mj.app.cli as cli

    assert all(m in sys.modules for m in scan(cli.__name__))


def test_every_gymnasium_id_names_a_registered_task():
    """`gym_ids.ENVS` is written out (importing the package must not import the tasks): it may
    name no task that `TASKS` lacks."""
    from macrostate_mj.env.task import TASKS
    from macrostate_mj.gym_ids import ENVS

    assert {kw["task"] for kw in ENVS.values() if "task" in kw} <= set(TASKS)
    assert TASKS.names() == ("caging", "explore", "localize")


def test_user_picked_tail_names_are_registries():
    """The collection's policies and SRS picks: the CLI's choices and the library's check are
    one registry each."""
    from macrostate_mj.tails.collection import POLICIES, PolicyConfig
    from macrostate_mj.tails.srs import PICKS, check_srs

    assert list(POLICIES) == ["passive", "random"] and list(PICKS) == ["max", "q3", "med", "q2"]
    with pytest.raises(UserError, match="unknown policy 'wild'; choose from passive, random"):
        PolicyConfig("wild")
    with pytest.raises(UserError, match="unknown SRS pick 'q1'; choose from max, q3, med, q2"):
        check_srs("q1", 30, 0.75)


def test_the_cli_lists_one_class_methods_and_model_kinds_without_torch():
    code = ("import sys; from estimators.oneclass import METHODS; "
            "from estimators.retlo import MODEL_KINDS; "
            "assert list(METHODS) == ['ofw', 'dcae', 'ocsvm', 'dsvdd', 'gen', 'ngen', 'iogen']; "
            "assert list(MODEL_KINDS) == ['fc', 'lstm'] and MODEL_KINDS['lstm'].history; "
            "assert 'torch' not in sys.modules")
    subprocess.run([sys.executable, "-c", code], check=True)
