"""One registry pattern: entries register by decorator where they are defined; an unknown name
is one line naming the choices."""

import subprocess
import sys

import pytest

from macrostate_mj.core.errors import UserError
from macrostate_mj.core.registry import Registry


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


def test_a_registry_imports_its_modules_on_first_read_only():
    code = ("import sys; from macrostate_mj.app.bench import SUITES; "
            "assert 'macrostate_mj.app.bench.srs' not in sys.modules; "
            "assert SUITES.names()[:3] == ('sim', 'render', 'env'); "
            "assert 'macrostate_mj.app.bench.srs' in sys.modules")
    subprocess.run([sys.executable, "-c", code], check=True)


def test_every_experiment_module_registers_itself():
    from macrostate_mj.app.experiments import EXPERIMENTS, names, registry

    assert list(registry()) == names() and set(EXPERIMENTS) == set(names())


def test_the_cli_lists_one_class_methods_and_model_kinds_without_torch():
    code = ("import sys; from estimators.oneclass import METHODS; "
            "from estimators.retlo import MODEL_KINDS; "
            "assert list(METHODS) == ['ofw', 'dcae', 'ocsvm', 'dsvdd', 'gen', 'ngen', 'iogen']; "
            "assert list(MODEL_KINDS) == ['fc', 'lstm'] and MODEL_KINDS['lstm'].history; "
            "assert 'torch' not in sys.modules")
    subprocess.run([sys.executable, "-c", code], check=True)
