"""`experiment list`, and every `experiment NAME` command, generated from its experiment module.

An experiment declares its flags where its settings live: each `Config` field the command sets
carries a `params.flag` (the option, with the one validation layer's checks); settings that are
not one field are the module's `FLAGS`, whose values its `configure(config, changes, ...)`
turns into more changes. The command adds what every run has (`--profile`, `--quick`, `--out`,
`--overwrite`, and `--workers` and `--ray` where the module's `PARALLEL` says its tasks spread),
calls the module's `validate` where it has one (bad input is refused before the folder is
claimed) and launches the run. The commands are built on first use, so `macrostate-mj --help`
imports no experiment.
"""

from __future__ import annotations

import copy
import inspect
import typing
from collections.abc import Callable, Iterator, MutableMapping
from dataclasses import MISSING, fields, is_dataclass, replace
from pathlib import Path
from types import ModuleType, UnionType
from typing import Any

import typer
import typer.core

from macrostate_mj.app.cli.app import app
from macrostate_mj.app.params import (
    FLAG,
    MAX_WORKERS,
    PROFILE,
    Choice,
    Count,
    Flag,
    OutputDir,
    Switch,
)


class _Commands(MutableMapping):
    """The group's commands: those added as usual, then each experiment's, built when named."""

    def __init__(self, given: dict) -> None:
        self._built = dict(given)

    def _names(self) -> list[str]:
        from macrostate_mj.app.experiments import names

        return [*self._built, *(n for n in names() if n not in self._built)]

    def __getitem__(self, name: str) -> Any:
        if name not in self._built:
            if name not in self._names():
                raise KeyError(name)
            self._built[name] = typer.main.get_command(_app_of(name))
        return self._built[name]

    def __setitem__(self, name: str, command: Any) -> None:
        self._built[name] = command

    def __delitem__(self, name: str) -> None:
        del self._built[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._names())

    def __len__(self) -> int:
        return len(self._names())


class ExperimentGroup(typer.core.TyperGroup):
    """`experiment`: its commands generated from the experiment registry on first use."""

    def __init__(self, **kw: Any) -> None:
        super().__init__(**kw)
        self.commands = _Commands(self.commands)


experiment_app = typer.Typer(cls=ExperimentGroup, no_args_is_help=True,
                             help="Reproduce a figure or table of the dissertation.")
app.add_typer(experiment_app, name="experiment")


@experiment_app.command("list")
def experiment_list() -> None:
    """Name every experiment with its profiles and what it reproduces."""
    from macrostate_mj.app.experiments import registry

    found = registry()
    width = max(len(", ".join(m.PROFILES)) for m in found.values())
    for name, module in found.items():
        typer.echo(f"{name:<12} profiles: {', '.join(module.PROFILES):<{width}}  "
                   f"{_help(module)}")


def launch(name: str, config: Any, out: Path, overwrite: bool, workers: int = 1,
           ray: str | None = None) -> None:
    """Run experiment `name` under the run lifecycle with a bar per stage; print its lines."""
    from macrostate_mj.app.experiments import execute
    from macrostate_mj.core.progress import stage_progress

    with stage_progress() as report:
        lines = execute(name, config, out, overwrite, workers, ray, report)
    for line in lines:
        typer.echo(line)


def _app_of(name: str) -> typer.Typer:
    """A one-command Typer app holding `experiment NAME`, generated from its module."""
    from macrostate_mj.app.experiments import experiment

    sub = typer.Typer(add_completion=False)
    sub.command(name)(command(name, experiment(name)))
    return sub


def _shown(value: Any) -> str:
    if isinstance(value, tuple):
        return ", ".join(_shown(v) for v in value) or "none"
    return "none" if value is None else str(getattr(value, "name", value))


def _profile_default(module: ModuleType, name: str, f: Flag) -> str:
    """What the help shows as a field flag's default: the profiles' values (one when alike),
    or the flag's own, said to hold whatever the profile."""
    show = (lambda v: ",".join(map(str, v))) if f.type is str else _shown
    if f.default is not PROFILE:
        return f"{f.shown or show(f.default)}, whatever the profile"
    if f.shown:
        return f.shown
    values = {p: show(getattr(config, name)) for p, config in module.PROFILES.items()}
    if len(set(values.values())) == 1:
        return next(iter(values.values()))
    return "; ".join(f"{p}: {v}" for p, v in values.items())


def _annotation(hint: Any) -> Any:
    """The type typer parses a field's flag as: a repeatable option for a tuple, the inner
    type of an optional."""
    if isinstance(hint, UnionType) or typing.get_origin(hint) is typing.Union:
        inner = [a for a in typing.get_args(hint) if a is not type(None)]
        hint = inner[0] if len(inner) == 1 else str
    simple = (int, float, bool, str, Path)
    if typing.get_origin(hint) in (tuple, list):
        inner = typing.get_args(hint)[0]
        return list[inner if inner in simple else str]
    return hint if hint in simple else str


def _profiles_help(module: ModuleType) -> str:
    """Each profile by what it changes from `full` (generated, so it cannot go stale): as the
    flag that would set it, or as `name=value` where only the profile does."""
    full = module.PROFILES["full"]
    options = {f.name: f.metadata[FLAG].option for f in fields(module.Config) if FLAG in
               f.metadata} | dict(getattr(module, "FLAGS", {}))
    flags = {name: next((d.split("/")[0] for d in option.param_decls if d.startswith("--")),
                        f"--{name.replace('_', '-')}") for name, option in options.items()}
    parts = [f"{name}: {', '.join(_changes(config, full, flags)) or 'the dissertation sizes'}"
             for name, config in module.PROFILES.items()]
    return (f"The settings the flags start from ({'; '.join(parts)}); a flag not given keeps "
            "the profile's value unless its default says otherwise.")


def _changes(config: Any, full: Any, flags: dict[str, str], prefix: str = "") -> list[str]:
    """What `config` sets differently from `full`: "--flag value" for a setting with a flag
    (`flags`, by field name), "name=value" otherwise, nested configs by their own settings."""
    changed = []
    for f in fields(config):
        mine, theirs = getattr(config, f.name), getattr(full, f.name)
        if mine == theirs:
            continue
        name = prefix + f.name.replace("_", "-")
        if is_dataclass(mine) and type(mine) is type(theirs):
            changed += _changes(mine, theirs, {}, f"{name}.")
        elif f.name in flags:
            changed.append(f"{flags[f.name]} {_shown(mine)}")
        else:
            changed.append(f"{name}={_shown(mine)}")
    return changed


def command(name: str, module: ModuleType) -> Callable[..., None]:
    """The `experiment NAME` callback, its parameters declared by `module` (see the top)."""
    hints = typing.get_type_hints(module.Config)
    params: list[inspect.Parameter] = []
    field_flags: dict[str, Flag] = {}

    def add(pname: str, annotation: Any, option: Any) -> None:
        params.append(inspect.Parameter(pname, inspect.Parameter.KEYWORD_ONLY,
                                        default=option, annotation=annotation))

    add("profile", str, Choice("full", _profiles_help(module), tuple(module.PROFILES)))
    if "quick" in module.PROFILES:
        add("quick", bool, Switch(False, "Shorthand for --profile quick."))
    for f in fields(module.Config):
        declared = f.metadata.get(FLAG)
        if declared is None:
            continue
        option = copy.copy(declared.option)
        required = declared.default is ... or (
            declared.default is PROFILE and f.default is MISSING
            and f.default_factory is MISSING)
        option.default = ... if required else (
            None if declared.default is PROFILE else declared.default)
        option.show_default = False if required else _profile_default(module, f.name, declared)
        field_flags[f.name] = declared
        add(f.name, declared.type or _annotation(hints[f.name]), option)
    extras = dict(getattr(module, "FLAGS", {}))
    named = {f.name for f in fields(module.Config)}
    for pname, option in extras.items():
        if option.default is None and pname in named:    # a field's, the profile's by default
            option = copy.copy(option)
            option.show_default = _profile_default(module, pname, Flag(option))
        add(pname, _annotation(typing.get_type_hints(module.configure)[pname]), option)
    parallel = getattr(module, "PARALLEL", None)
    if parallel is not None:
        add("workers", int, Count(1, f"Local worker processes ({parallel.workers}); the "
                                  "results do not depend on it.", max=MAX_WORKERS))
        if parallel.ray:
            add("ray", str, typer.Option(None, "--ray", help="Run the tasks on Ray: local, "
                                         "auto or ADDRESS."))
    add("out", Path, OutputDir(..., f"Output folder ({', '.join(module.PRODUCTS)}; its "
                               "tasks are cached in it)."))
    add("overwrite", bool, Switch(False, "Replace the products of a finished run (cached "
                                  "tasks are kept; delete the folder to start over)."))

    def run(**given: Any) -> None:
        from macrostate_mj.app.experiments import profile
        from macrostate_mj.core.errors import UserError

        if given.get("quick") and given["profile"] not in ("full", "quick"):
            raise UserError(f"means --profile quick; drop it or --profile "
                            f"{given['profile']}", "quick")
        chosen = "quick" if given.get("quick") else given["profile"]
        config = profile(name, chosen)
        changes = {}
        for fname, declared in field_flags.items():
            value = given[fname]
            if value is None and declared.default is PROFILE:
                continue
            if isinstance(value, list):
                value = tuple(value)
            changes[fname] = declared.parse(value) if declared.parse and value is not None \
                else value
        if extras:          # one `replace`: a config checks itself whole
            changes |= module.configure(config, changes, profile=chosen,
                                        workers=given.get("workers", 1),
                                        **{k: given[k] for k in extras})
        config = replace(config, **changes)
        if hasattr(module, "validate"):
            module.validate(config)
        launch(name, config, given["out"], given["overwrite"], given.get("workers", 1),
               given.get("ray"))

    run.__signature__ = inspect.Signature(params)  # type: ignore[attr-defined]
    run.__annotations__ = {p.name: p.annotation for p in params}
    run.__doc__ = _help(module)
    run.__name__ = f"experiment_{name.replace('-', '_')}"
    return run


def _help(module: ModuleType) -> str:
    """The command's help: the first paragraph of the module's docstring (which the module's
    own documentation continues), less its "`experiment x`:"."""
    doc = (module.__doc__ or "").strip().split("\n\n")[0].split(":", 1)[-1]
    text = " ".join(doc.split())
    return text[:1].upper() + text[1:]
