"""Scenario files: a lab described in TOML, resolved once into a typed `ScenarioConfig`.

A file may `extends = "lab"` (a built-in name) or `extends = "other.toml"` (a path, relative to
the file) and override any key; tables merge key by key, everything else is replaced. The three
built-in scenarios are such files, shipped in the package (`assets/scenarios/*.toml`).

The schema is the dataclasses themselves (`ScenarioConfig` and its parts): a key the schema does
not have, a value of the wrong type, or a value the config refuses is one `UserError` naming the
key and the file. Why dataclasses rather than pydantic: the config is already a tree of frozen
dataclasses that travels to workers and into cache keys, and the checks a scenario needs (units,
a camera that sees the arena, rates that divide into physics steps) are the config's own; a
second model of the same tree would be a second home for it.
"""

from __future__ import annotations

import math
import tomllib
import types
import typing
from dataclasses import MISSING, fields, is_dataclass
from importlib.resources import files
from pathlib import Path
from typing import Any

from macrostate_mj.chain import markers, motion, planners, scene, tags
from macrostate_mj.chain.noise import NoiseConfig
from macrostate_mj.chain.scenario import LAYOUT, NESTED, ScenarioConfig, file_key
from macrostate_mj.core.errors import UserError

BUILTIN = Path(str(files("macrostate_mj") / "assets" / "scenarios"))

PLANNERS = {"psi_grid": planners.PsiGrid, "cell_walk": planners.CellWalk,
            "preset_twists": planners.PresetTwists, "park": planners.Park}
FOLLOWERS = {"two_neighbours": motion.TwoNeighbours, "wait_for_behind": motion.WaitForBehind}
MARKERS = {"colour": markers.ColourMarkers, "aruco": tags.ArucoMarkers}
RULES = {"planner": PLANNERS, "followers": FOLLOWERS, "markers": MARKERS}   # chosen by `kind`
WALL_KEYS = {"walls", "wall_height", "wall_thickness"}
AUTO = "auto"      # an optional value left to its default (a camera framing the arena)


def is_file_ref(ref: str | Path) -> bool:
    """A path to a scenario file, rather than a built-in's name."""
    return isinstance(ref, Path) or str(ref).endswith(".toml") or "/" in str(ref)


def builtin_names() -> list[str]:
    return sorted(p.stem for p in BUILTIN.glob("*.toml"))


def load_scenario(ref: str | Path) -> ScenarioConfig:
    """A built-in scenario by name, or a scenario file by path, fully resolved and checked."""
    table, source = resolve(ref)
    return to_config(table, source)


def resolve(ref: str | Path, seen: tuple[Path, ...] = ()) -> tuple[dict, str]:
    """The file's table with everything it extends merged under it; where it came from."""
    path = _path_of(ref)
    if path in seen:
        raise UserError(f"{path}: `extends` loops back to itself; remove the cycle")
    try:
        table = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as err:
        raise UserError(f"{path}: not valid TOML ({err}); fix the file") from None
    except OSError as err:
        raise UserError(f"cannot read scenario file {path} ({err.strerror})") from None
    _anchor_robot(table, path)
    base = table.pop("extends", None)
    if base is None:
        return table, str(path)
    if not isinstance(base, str):
        raise UserError(f"{path}: `extends` must be a scenario name or a file path, got {base!r}")
    ref = base if not is_file_ref(base) else path.parent / base
    parent, _ = resolve(ref, (*seen, path))
    return _merge(parent, table), str(path)


def _anchor_robot(table: dict, path: Path) -> None:
    """A relative `robot.model` path is relative to the file that says it (not to the working
    directory, nor to a file that extends it)."""
    robot = table.get("robot")
    model = robot.get("model") if isinstance(robot, dict) else None
    if isinstance(model, str) and ("/" in model or model.endswith(".xml")):
        if not Path(model).expanduser().is_absolute():
            robot["model"] = str(path.parent / model)


def _path_of(ref: str | Path) -> Path:
    if is_file_ref(ref):
        path = Path(ref)
        if not path.is_file():
            raise UserError(f"no scenario file {path}; pass a .toml file or one of "
                            f"{', '.join(builtin_names())}")
        return path.resolve()
    path = BUILTIN / f"{ref}.toml"
    if not path.is_file():
        raise UserError(f"unknown scenario {ref!r}; choose one of {', '.join(builtin_names())} "
                        "or pass a scenario file (.toml)")
    return path


def _merge(base: dict, over: dict) -> dict:
    """Tables merge key by key, except a rule table of another `kind` (a planner or follower
    rule of another kind has other keys): it replaces the inherited one."""
    out = dict(base)
    for key, value in over.items():
        inherited = out.get(key)
        if (isinstance(value, dict) and isinstance(inherited, dict)
                and value.get("kind", inherited.get("kind")) == inherited.get("kind")):
            out[key] = _merge(inherited, value)
        else:
            out[key] = value
    return out


def to_config(table: dict, source: str) -> ScenarioConfig:
    """The typed config of a resolved table; bad keys and values name the key and the file."""
    kw: dict[str, Any] = {}
    for section, value in table.items():
        if section in LAYOUT and section:
            _section(value, section, source, kw)
        elif section in NESTED:
            kw[NESTED[section]] = _dataclass(_field_type(NESTED[section]), value, section,
                                             source)
        elif section in RULES:
            kw[section] = _rule(value, section, source)
        elif section in LAYOUT[""]:
            kw[LAYOUT[""][section]] = value
        else:
            tables = sorted({*LAYOUT, *NESTED, *RULES} - {""})
            raise UserError(f"{source}: unknown key {section!r}; the tables are "
                            f"{', '.join(tables)}")
    arena = table.get("arena", {})
    if WALL_KEYS & set(arena):
        walls = arena.get("walls", True)
        if not isinstance(walls, bool):
            raise UserError(f"{source}: arena.walls must be true or false, got {walls!r}")
        kw["walls"] = None if not walls else scene.Walls(
            **{k: _number(arena[f"wall_{k}"], f"arena.wall_{k}", source, positive=True)
               for k in ("height", "thickness") if f"wall_{k}" in arena})
    missing = [f.name for f in fields(ScenarioConfig) if f.default is MISSING
               and f.default_factory is MISSING and f.name not in kw]
    if missing:
        raise UserError(f"{source}: missing {', '.join(file_key(m) for m in missing)}; add it "
                        "or `extends` a built-in scenario")
    return _checked(ScenarioConfig, kw, "", source)


def _section(value: Any, section: str, source: str, kw: dict) -> None:
    if not isinstance(value, dict):
        raise UserError(f"{source}: `{section}` must be a table ([{section}]), got {value!r}")
    keys = LAYOUT[section]
    extra = WALL_KEYS if section == "arena" else set()
    if section == "noise":          # beside marker_jitter, the imaging noise (`NoiseConfig`)
        extra = {f.name for f in fields(NoiseConfig)}
        imaging = {k: v for k, v in value.items() if k in extra}
        if imaging:
            kw["imaging"] = _dataclass(NoiseConfig, imaging, "noise", source)
    for key, v in value.items():
        if key in extra:
            continue
        if key not in keys:
            raise UserError(f"{source}: unknown key {section}.{key}; {section} takes "
                            f"{', '.join(sorted({*keys, *extra}))}")
        kw[keys[key]] = _typed(v, _field_type(keys[key]), f"{section}.{key}", source)


def _rule(value: Any, section: str, source: str) -> object:
    """`[planner] kind = "psi_grid"` (+ its fields), `followers = "two_neighbours"` or
    `[markers] kind = "colour"`: the behaviour's object, chosen by the file's name for it."""
    kinds = RULES[section]
    table = {"kind": value} if isinstance(value, str) else dict(value)
    kind = table.pop("kind", None)
    if kind not in kinds:
        raise UserError(f"{source}: {section}.kind must be one of {', '.join(kinds)}, "
                        f"got {kind!r}")
    return _dataclass(kinds[kind], table, section, source)


def _dataclass(cls: type, value: Any, where: str, source: str) -> Any:
    if not isinstance(value, dict):
        raise UserError(f"{source}: `{where}` must be a table, got {value!r}")
    hints = typing.get_type_hints(cls)
    names = {f.name for f in fields(cls)}
    kw = {}
    for key, v in value.items():
        if key not in names:
            raise UserError(f"{source}: unknown key {where}.{key}; {where} takes "
                            f"{', '.join(sorted(names)) or 'no keys'}")
        kw[key] = _typed(v, hints[key], f"{where}.{key}", source)
    return _checked(cls, kw, where, source)


def _checked(cls: type, kw: dict, where: str, source: str) -> Any:
    try:
        return cls(**kw)
    except UserError as err:
        raise UserError(f"{source}: {err}") from None
    except TypeError as err:
        raise UserError(f"{source}: {where or 'scenario'}: {err}") from None


def _typed(value: Any, hint: Any, key: str, source: str) -> Any:
    """`value` as the schema's type `hint` (lists become tuples; numbers finite)."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (types.UnionType, typing.Union):
        if value == AUTO and type(None) in args:     # the default: framed, MuJoCo's own
            return None
        hint = next(a for a in args if a is not type(None))
        return _typed(value, hint, key, source)
    if origin is tuple:
        if not isinstance(value, list):
            raise UserError(f"{source}: {key} must be a list, got {value!r}")
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_typed(v, args[0], f"{key}[{i}]", source) for i, v in enumerate(value))
        if len(value) != len(args):
            raise UserError(f"{source}: {key} must have {len(args)} values, got {len(value)}")
        return tuple(_typed(v, a, key, source) for v, a in zip(value, args, strict=True))
    if hint is bool:
        if not isinstance(value, bool):
            raise UserError(f"{source}: {key} must be true or false, got {value!r}")
        return value
    if hint in (float, int):
        number = _number(value, key, source)
        if hint is int and number != int(number):
            raise UserError(f"{source}: {key} must be a whole number, got {value!r}")
        return int(number) if hint is int else float(number)
    if hint is str:
        if not isinstance(value, str):
            raise UserError(f"{source}: {key} must be a string, got {value!r}")
        return value
    if is_dataclass(hint):
        return _dataclass(hint, value, key, source)
    return value


def _number(value: Any, key: str, source: str, positive: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise UserError(f"{source}: {key} must be a finite number, got {value!r}")
    if positive and not value > 0:
        raise UserError(f"{source}: {key} must be positive, got {value!r}")
    return value


def _field_type(name: str) -> Any:
    return typing.get_type_hints(ScenarioConfig)[name]


def to_toml(cfg: ScenarioConfig) -> str:
    """The resolved scenario as a scenario file (`scenario show`): every key, no `extends`;
    loading it gives `cfg` again."""
    sections: dict[str, dict[str, Any]] = {s: {} for s in LAYOUT}
    for section, keys in LAYOUT.items():
        for key, name in keys.items():
            sections[section][key] = getattr(cfg, name)
    arena = sections["arena"]
    arena["walls"] = cfg.walls is not None
    if cfg.walls is not None:
        arena["wall_height"], arena["wall_thickness"] = cfg.walls.height, cfg.walls.thickness
    sections["noise"].update(_fields(cfg.imaging))
    for table, name in NESTED.items():
        sections[table] = _fields(getattr(cfg, name))
    for section, kinds in RULES.items():
        rule = getattr(cfg, section)
        kind = next(k for k, cls in kinds.items() if type(rule) is cls)
        sections[section] = {"kind": kind, **_fields(rule)}
    lines = [f"{k} = {_toml(v)}" for k, v in sections.pop("").items()]
    for section, values in sections.items():
        lines += ["", f"[{section}]", *(f"{k} = {_toml(AUTO if v is None else v)}"
                                        for k, v in values.items())]
    return "\n".join(lines) + "\n"


def _fields(obj: Any) -> dict[str, Any]:
    return {f.name: getattr(obj, f.name) for f in fields(obj)}


def _toml(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, int | float):
        return repr(value)
    if isinstance(value, tuple | list):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    if is_dataclass(value) and not isinstance(value, type):     # an inline table (obstacles)
        return "{" + ", ".join(f"{k} = {_toml(v)}" for k, v in _fields(value).items()) + "}"
    raise TypeError(f"no TOML form for {value!r}")
