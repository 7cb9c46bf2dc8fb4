"""The CLI's one validation layer: options that check themselves while the command line is parsed.

Every number, path and choice a command takes is declared through these factories, so a bad
value fails before anything is imported, built or written, as one line naming the option (the
parser's error, exit 2). Output paths are also registered here, so that `finish` can remove an
output a failed command created: bad input leaves nothing behind, and a run that fails or is
interrupted keeps what it finished (its resumable shards, its poses up to the fault) but no
empty folder. `tests/app/test_params.py` checks that every option of every command comes from
here.

An experiment's config declares its flags on its fields with the same factories (`flag`), and
`experiment NAME` is generated from them (`app.cli.experiments`).
"""

from __future__ import annotations

import math
import shutil
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import typer

from estimators.retlo import UNCERTAINTIES
from macrostate_mj.formats.thymioloc import DEFAULT_PX_PER_CM

SEED_MAX = 2**63 - 1   # seeds travel through numpy, JSON and Parquet int64
COUNT_MAX = 10**9      # a count beyond this is a typo (and would overflow what it sizes)
MAX_WORKERS = 256      # processes or threads on one machine
MAX_SECONDS = 1e6      # about 11.6 simulated days: longer is a typo, not an experiment
_outputs: list[tuple[Path, bool]] = []   # (path, existed before this command)


def _each(value: Any) -> list:
    return list(value) if isinstance(value, list | tuple) else [value]


def _flags(flag: str | None) -> list[str]:
    return [flag] if flag else []


def _checked(check: Callable[[Any], None], role: str) -> Callable:
    """A typer callback that applies `check` to the value (each value of a repeatable option)
    and leaves None (an option not given) alone; the parser's error names the option. `role`
    (number, choice, input_file, input_dir, output_file, output_dir) tells the tests what to
    throw at it."""

    def callback(value: Any) -> Any:
        for v in _each(value):
            if v is not None:
                check(v)
        return value

    callback.role = role  # type: ignore[attr-defined]
    return callback


def _fail(message: str) -> None:
    raise typer.BadParameter(message)


def _number(lo: float, lo_open: bool, hi: float | None) -> Callable[[Any], None]:
    def check(v: float) -> None:
        if not math.isfinite(v):
            _fail(f"must be a finite number, got {v}")
        if (v <= lo if lo_open else v < lo):
            _fail(f"must be {'positive' if lo_open else 'non-negative'}, got {v:g}")
        if hi is not None and v > hi:
            _fail(f"must be at most {hi:g}, got {v:g}")
    return check


def Seed(default: int = 0, help: str = "Seed of every random draw.", **kw: Any) -> Any:  # noqa: N802
    """A seed: an integer 0..2^63-1 (numpy refuses negative seeds)."""
    return typer.Option(default, help=f"{help} (0..2^63-1)", min=0, max=SEED_MAX, **kw)


def Count(default: Any, help: str, min: int = 1, max: int = COUNT_MAX, **kw: Any) -> Any:  # noqa: N802
    """An integer count with bounds (click checks them and names the option)."""
    return typer.Option(default, help=help, min=min, max=max, **kw)


def Positive(default: Any, help: str, flag: str | None = None, max: float | None = None,  # noqa: N802
             **kw: Any) -> Any:
    """A finite number > 0 (durations, rates, scales)."""
    return typer.Option(default, *_flags(flag), help=help,
                        callback=_checked(_number(0, True, max), "number"), **kw)


def NonNegative(default: Any, help: str, max: float | None = None, **kw: Any) -> Any:  # noqa: N802
    """A finite number >= 0."""
    return typer.Option(default, help=help,
                        callback=_checked(_number(0, False, max), "number"), **kw)


def Fraction(default: Any, help: str, **kw: Any) -> Any:  # noqa: N802
    """A finite number in [0, 1)."""
    def check(v: float) -> None:
        if not (math.isfinite(v) and 0 <= v < 1):
            _fail(f"must be a fraction in [0, 1), got {v}")
    return typer.Option(default, help=help, callback=_checked(check, "number"), **kw)


def Choice(default: Any, help: str, choices: Sequence[str], flag: str | None = None,  # noqa: N802
           **kw: Any) -> Any:
    """One of `choices` (each, when repeatable), listed in the help text."""
    return typer.Option(default, *_flags(flag), help=f"{help} One of: {', '.join(choices)}.",
                        callback=_checked(_one_of(choices), "choice"), **kw)


def _one_of(choices: Sequence[str]) -> Callable[[str], None]:
    def check(v: str) -> None:
        if v not in choices:
            _fail(f"{v!r} is not one of {', '.join(choices)}")
    return check


def Device() -> Any:  # noqa: N802
    """`--device`: where torch trains; cuda only where torch sees a GPU (checked while parsing,
    so a run never starts on a device it cannot use)."""
    devices = ("cpu", "cuda")
    known = _one_of(devices)

    def check(v: str) -> None:
        known(v)
        if v == "cuda":
            import torch

            if not torch.cuda.is_available():
                _fail("cuda: torch sees no GPU here; use --device cpu")
    return typer.Option("cpu", help=f"Where torch trains. One of: {', '.join(devices)}.",
                        callback=_checked(check, "choice"))


def Precision() -> Any:  # noqa: N802
    """`--precision`: the training forward passes' arithmetic (`estimators.precision`)."""
    from estimators.precision import PRECISIONS

    return Choice("fp32", "Training arithmetic: fp32, or bf16 (mixed precision: faster on a "
                  "CPU with AVX512-BF16 or a GPU, slower elsewhere; every committed figure is "
                  "fp32; what bf16 changes: docs, how-to/resume-and-scale).", tuple(PRECISIONS))


def _resolve_scenario() -> Callable[[Any], Any]:
    """A callback resolving a built-in scenario's name or a scenario file, once: the command
    and every worker it starts get the typed config (a bad file fails while parsing, naming
    its key)."""

    def resolve(value: Any) -> Any:
        from macrostate_mj.chain.scenarios import get_scenario
        from macrostate_mj.core.errors import UserError

        if value is None or not isinstance(value, str | Path):
            return value
        try:
            return get_scenario(value)
        except UserError as err:
            _fail(str(err))

    resolve.role = "choice"  # type: ignore[attr-defined]
    return resolve


def Scenarios(help: str) -> Any:  # noqa: N802
    """`--scenario`, repeatable: each a built-in's name or a scenario file, resolved once while
    parsing (a bad one fails naming the option)."""
    resolve = _resolve_scenario()

    def each(values: Any) -> Any:
        return values if values is None else [resolve(v) for v in values]

    each.role = "choice"  # type: ignore[attr-defined]
    return typer.Option(None, "--scenario", callback=each, help=f"{help} A built-in scenario "
                        "or a scenario file (.toml; `scenario show lab` prints one).")


def DatasetNames() -> Any:  # noqa: N802
    """Published datasets as a command's arguments, by name (`all` for every one)."""
    def check(v: str) -> None:
        from macrostate_mj.core.datasets import named

        named([v])

    return typer.Argument(..., help="The datasets: retlo (the ThymioLoc poses), hsants (the ant "
                          "flows), hsants-dev (the dev set of unstable flows, picked from "
                          "hsants), or all.",
                          callback=_checked(check, "choice"))


def ScenarioArg() -> Any:  # noqa: N802
    """A scenario as a command's argument (`scenario show lab`)."""
    return typer.Argument(..., help="A built-in scenario's name or a scenario file (.toml).",
                          callback=_resolve_scenario())


def _scenario() -> Any:
    from macrostate_mj.chain.scenarios import SCENARIOS

    return typer.Option("lab", callback=_resolve_scenario(), help="A built-in scenario (one "
                        f"of: {', '.join(SCENARIOS)}) or a scenario file (.toml; `scenario "
                        "show lab` prints one to start from).")


def _input_file(suffixes: tuple[str, ...]) -> Callable[[Path, str], None]:
    def check(p: Path) -> None:
        if p.is_dir():
            _fail(f"{p} is a folder; give a file")
        if not p.is_file():
            _fail(f"{p} does not exist")
        if suffixes and p.suffix.lower() not in suffixes:
            _fail(f"{p} is not a {' or '.join(suffixes)} file")
    return check


def InputFile(default: Any, help: str, suffixes: tuple[str, ...] = (),  # noqa: N802
              flag: str | None = None, **kw: Any) -> Any:
    """An existing file (not a folder); repeatable when declared as a list."""
    return typer.Option(default, *_flags(flag), help=help,
                        callback=_checked(_input_file(suffixes), "input_file"), **kw)


def InputFileOr(default: Any, help: str, names: tuple[str, ...],  # noqa: N802
                suffixes: tuple[str, ...] = ()) -> Any:
    """An existing file, or one of `names` (a built-in that needs no file)."""
    files = _input_file(suffixes)

    def check(value: str) -> None:
        if value in names:
            return
        if not Path(value).exists():
            _fail(f"{value} is neither a file nor one of {', '.join(names)}")
        files(Path(value))
    return typer.Option(default, help=help, callback=_checked(check, "input_file"))


def InputFiles(help: str, suffixes: tuple[str, ...] = ()) -> Any:  # noqa: N802
    """Positional existing files."""
    return typer.Argument(..., help=help, callback=_checked(_input_file(suffixes), "input_file"))


def _input_dir(p: Path) -> None:
    if p.is_file():
        _fail(f"{p} is a file; give a folder")
    if not p.is_dir():
        _fail(f"{p} does not exist")


def InputDir(default: Any, help: str, **kw: Any) -> Any:  # noqa: N802
    """An existing folder."""
    return typer.Option(default, help=help, callback=_checked(_input_dir, "input_dir"), **kw)


def _writable_parent(p: Path) -> None:
    probe = p.parent
    while not probe.exists():
        probe = probe.parent
    if not probe.is_dir():
        _fail(f"cannot create {p}: {probe} is a file")


def _output_file(suffixes: tuple[str, ...]) -> Callable[[Path, str], None]:
    def check(p: Path) -> None:
        if suffixes and p.suffix.lower() not in suffixes:
            _fail(f"{p} needs the {' or '.join(suffixes)} extension")
        if p.is_dir():
            _fail(f"{p} is a folder; give a file path")
        _writable_parent(p)
        _outputs.append((p, p.exists()))
    return check


def OutputFile(default: Any, help: str, suffixes: tuple[str, ...] = (), **kw: Any) -> Any:  # noqa: N802
    """A file to write: the right extension, not a folder; removed if a failed command made it."""
    return typer.Option(default, help=help,
                        callback=_checked(_output_file(suffixes), "output_file"), **kw)


def _output_dir(p: Path) -> None:
    if p.exists() and not p.is_dir():
        _fail(f"{p} is a file; give a folder path")
    _writable_parent(p)
    _outputs.append((p, p.exists()))


def OutputDir(default: Any, help: str, flag: str | None = None, **kw: Any) -> Any:  # noqa: N802
    """A folder to write into; removed if a failed command created it and left it empty (or if
    the failure was bad input)."""
    return typer.Option(default, *_flags(flag), help=help,
                        callback=_checked(_output_dir, "output_dir"), **kw)


def begin() -> None:
    """Forget the outputs of an earlier command (in-process callers run several)."""
    _outputs.clear()


def _empty(p: Path) -> bool:
    return p.is_dir() and all(_empty(c) for c in p.iterdir())


def finish(bad_input: bool) -> None:
    """After a failed command: remove each output it created, when the failure was bad input
    (nothing half-written) or when nothing was written into it (no empty folder)."""
    for path, existed in reversed(_outputs):
        if existed or not path.exists():
            continue
        if path.is_dir() and (bad_input or _empty(path)):
            shutil.rmtree(path, ignore_errors=True)
        elif path.is_file() and bad_input:
            path.unlink(missing_ok=True)
    _outputs.clear()


def Switch(default: bool, help: str, flag: str | None = None, **kw: Any) -> Any:  # noqa: N802
    """An on/off option, always with its --no- form."""
    return typer.Option(default, *_flags(flag), help=help, **kw)


Scenario = _scenario()
CSV = (".csv",)
PxPerCm = Positive(DEFAULT_PX_PER_CM, "Camera pixels per cm of the data (the real ThymioLoc set "
                   "and `collect`).", "--px-per-cm")
Uncertainty = Choice("none", "none: a point estimate per robot; gaussian: a 2-D Gaussian per "
                     "robot (mean and covariance), trained on its negative log-likelihood, "
                     "whose calibration the reports then carry; gaussian-faithful: the same, "
                     "its mean trained on the point model's loss.", UNCERTAINTIES)
History = Count(10, "Steps of history the module sees (ℓ; 10 in sections 2.6 and 3.3).",
                max=24)
Chained = Switch(True, "Also train on Followers carrying another instance's Head-estimate "
                 "error, as modules k >= 1 of a longer chain see them (docs: "
                 "decisions/chained-training).", "--chained/--no-chained")


PROFILE = "the profile's"   # a flag not given leaves the profile's value


@dataclass(frozen=True)
class Flag:
    """A config field's command-line flag: its option, declared with a factory above (its own
    default is replaced: not given, the field keeps the chosen profile's value, or `default`
    where the command has always meant another), how the parsed value becomes the field's
    (`parse`; a repeatable option arrives as a tuple), and what the help shows as its default
    where the value itself would not read well (`shown`: a machine's path)."""

    option: Any
    parse: Callable[[Any], Any] | None = None
    default: Any = PROFILE
    shown: str | None = None
    type: Any = None        # what the option parses, where not the field's type


FLAG = "flag"     # the `dataclasses.field` metadata key a `Flag` travels under


def flag(option: Any, parse: Callable[[Any], Any] | None = None, default: Any = PROFILE,
         shown: str | None = None, type: Any = None) -> dict[str, Flag]:  # noqa: A002
    """`field(metadata=...)` for a field the experiment's command sets (see `Flag`)."""
    return {FLAG: Flag(option, parse, default, shown, type)}


# the real 3-robot ThymioLoc folder an experiment reads (`field(metadata=REAL_FOLDER)`)
REAL_FOLDER = flag(InputDir(None, "Folder of the real ThymioLoc 3-robot Train.csv and Val.csv."),
                   shown="the published ones, `data fetch retlo`")
