"""Bad input, generated: every option of every command, thrown values it must refuse.

Each case asserts what a user sees: exit code 2, one line naming the option, no traceback, and
nothing left behind. The options are read from the CLI itself, so an option is covered the day
it is added, and one declared without the validation layer (`macrostate_mj.app.params`)
fails `test_every_option_goes_through_the_validation_layer`.
"""

from __future__ import annotations

import contextlib
import functools
import io
from pathlib import Path

import pytest
import typer.main
from conftest import REPO
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from macrostate_mj.app.cli import main
from macrostate_mj.app.cli.app import app
from macrostate_mj.app.experiments import experiment, names

# Options of free text that their commands parse (and test) themselves.
TEXT_OPTIONS = {"--overlays", "--ray", "--split", "--randomize", "--days", "--crop", "--splits",
                "--ms", "--model", "--set", "--ablate", "--mirror", "--only", "--base"}


def _commands() -> dict[str, object]:
    found = {}

    def walk(cmd, path: tuple[str, ...]) -> None:
        if hasattr(cmd, "commands"):
            for name, sub in cmd.commands.items():
                walk(sub, (*path, name))
        else:
            found[" ".join(path)] = cmd

    walk(typer.main.get_command(app), ())
    return found


COMMANDS = _commands()


def _role(p) -> str | None:
    return getattr(p.callback, "role", None)


def _rows(keep) -> list[tuple[str, str]]:
    return [(name, p.opts[0]) for name, cmd in COMMANDS.items() for p in cmd.params
            if p.param_type_name == "option" and keep(p)]


def _valid_args(tmp: Path) -> dict[str, list[str]]:
    """For every command, arguments that pass parsing (inputs exist, outputs are fresh): the
    experiments' generated from their modules (`experiment_args`), the rest written here."""
    csv, folder, out = tmp / "in.csv", tmp / "in_dir", tmp / "out"
    csv.write_text("")
    (tmp / "m.pt").write_bytes(b"")
    folder.mkdir(exist_ok=True)
    c, d = str(csv), str(folder)
    return {
        "simulate": ["--out", str(out)],
        "export-mjcf": ["--out", f"{out}.xml"],
        "collect": ["--minutes", "1", "--out", str(out)],
        "soak": ["--out", str(out)],
        "stats": [c],
        "claims": ["--results", str(REPO / "results"), "--chapter", "chapter4"],
        "data fetch": ["retlo", "--dir", str(out), "--mirror", "http://127.0.0.1:9/"],
        "train retlo": ["--model", "fc", "--train", c, "--val", c, "--out", f"{out}.pt"],
        "evaluate retlo": ["--model", "heuristic2x", "--data", c, "--out", f"{out}.json"],
        "calibrate retlo": ["--model", f"{tmp}/m.pt", "--val", c, "--out", f"{out}.pt"],
        "experiment list": [],
        "scenario show": ["lab"],
        "scenario check": ["lab"],
        "sysid": ["--train", c, "--val", c, "--out", str(out)],
        "ants simulate": ["--out", str(out)],
        "flow": ["--frames", d, "--out", str(out)],
        "oc train": ["--method", "dsvdd", "--data", d, "--out", str(out)],
        "oc evaluate": ["--model", d, "--data", d, "--out", f"{out}.json"],
        "bench": [],
        "view": [],
        "track": [c, "--robots", "3", "--out", str(out)],
    } | {f"experiment {name}": experiment_args(name, tmp) for name in names()}


@functools.cache
def _experiment_flags(name: str) -> tuple[tuple[str, str, str], ...]:
    """(flag, role, the full profile's path) of each flag `experiment_args` gives a value."""
    command = typer.main.get_command(app).commands["experiment"].commands[name]
    full = experiment(name).PROFILES["full"]
    flags = []
    for p in command.params:
        role, named = str(_role(p)), getattr(full, p.name, None)
        if p.required or (role.startswith(("input", "output")) and named):
            assert role.startswith(("input", "output")), f"{name} {p.opts[0]}: give it a value"
            named = named[0] if isinstance(named, tuple) else named
            flags.append((p.opts[0], role, str(named or "")))
    return tuple(flags)


def experiment_args(name: str, tmp: Path) -> list[str]:
    """`experiment NAME`'s valid arguments, generated from its command: each required flag,
    and each path flag whose profile names a path (the published data, the committed ledger:
    a test must neither need nor touch those), given a path of its kind in `tmp` (an input
    existing, an output fresh; `--out` is `tmp/out`)."""
    args = []
    for flag, role, named in _experiment_flags(name):
        if role == "output_dir":
            path = tmp / "out"
        elif role == "output_file":
            path = tmp / Path(named).name
        elif role == "input_dir":
            path = tmp / "in_dir"
            path.mkdir(exist_ok=True)
        else:
            path = tmp / f"in{Path(named).suffix}"
            path.touch()
        args += [flag, str(path)]
    return args


def _run(args: list[str]) -> tuple[int, str]:
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            main(args)
            code = 0
        except SystemExit as exc:
            code = int(exc.code or 0)
    return code, err.getvalue()


def _with(command: str, tmp: Path, flag: str, value: str) -> list[str]:
    args = list(_valid_args(tmp)[command])
    if flag in args:
        args[args.index(flag) + 1] = value
    else:
        args += [flag, value]
    return [*command.split(), *args]


def _assert_refused(args: list[str], flag: str, tmp: Path) -> None:
    code, err = _run(args)
    lines = err.strip().splitlines()
    assert code == 2, (args, err)
    assert len(lines) == 1 and lines[0].startswith("error: ") and "Traceback" not in err, err
    assert flag in lines[0], (flag, lines[0])
    assert not [p.name for p in tmp.iterdir() if p.name.startswith("out")], (args, err)


def test_the_table_covers_every_command(tmp_path):
    assert set(_valid_args(tmp_path)) == set(COMMANDS)


def test_every_option_goes_through_the_validation_layer():
    """Numbers carry bounds or a validating callback, paths a validating callback, switches a
    --no- form; the only free-text options are those their commands parse."""
    for name, cmd in COMMANDS.items():
        for p in cmd.params:
            flag = p.opts[0]
            if flag in ("--help", "--version") or flag in TEXT_OPTIONS:
                continue
            if getattr(p, "is_flag", False):
                assert p.secondary_opts, f"{name} {flag}: no --no- form"
            elif str(p.bare_type()) in ("int", "float", "<class 'int'>", "<class 'float'>"):
                assert p.min is not None or _role(p) == "number", (name, flag)
            else:
                assert _role(p) is not None, f"{name} {flag}: not declared through params"


NUMERIC = _rows(lambda p: _role(p) == "number" or getattr(p, "min", None) is not None)
COUNTS = _rows(lambda p: getattr(p, "max", None) is not None)
# Values no number option accepts: not finite, negative, or not a number at all.
BAD_NUMBERS = st.one_of(
    st.sampled_from(["nan", "inf", "-inf", "1e400", "-0.5", "two", "", "1,5"]),
    st.floats(max_value=-1e-6, allow_nan=False, allow_infinity=False).map(repr),
    st.integers(max_value=-1).map(str),
)
FAST = settings(max_examples=10, deadline=None, derandomize=True,
                suppress_health_check=[HealthCheck.function_scoped_fixture])


@pytest.mark.parametrize(("command", "flag"), NUMERIC, ids=[f"{c}:{f}" for c, f in NUMERIC])
@FAST
@given(value=BAD_NUMBERS)
def test_numbers_refuse_what_is_not_finite_or_negative(tmp_path, command, flag, value):
    _assert_refused(_with(command, tmp_path, flag, value), flag, tmp_path)


@pytest.mark.parametrize(("command", "flag"), COUNTS, ids=[f"{c}:{f}" for c, f in COUNTS])
@FAST
@given(value=st.integers(min_value=2**63, max_value=2**80))
def test_counts_refuse_values_past_their_bound(tmp_path, command, flag, value):
    _assert_refused(_with(command, tmp_path, flag, str(value)), flag, tmp_path)


PATHS = [(c, f, r) for c, f in _rows(lambda p: str(_role(p)).startswith(("in", "out")))
         for r in [next(_role(p) for p in COMMANDS[c].params if p.opts[0] == f)]]
SUFFIX = {"--video": ".mp4", "--rerun": ".rrd", "export-mjcf": ".xml", "train retlo": ".pt"}


@pytest.mark.parametrize(("command", "flag", "role"), PATHS,
                         ids=[f"{c}:{f}" for c, f, _ in PATHS])
def test_paths_of_the_wrong_kind_are_refused_and_left_alone(tmp_path, command, flag, role):
    """Inputs: missing, or a folder for a file (a file for a folder). Outputs: a file path that
    is a folder, or a folder path that is a file, even with --overwrite; neither is touched."""
    if role.startswith("input"):
        _assert_refused(_with(command, tmp_path, flag, str(tmp_path / "none" / "x.csv")), flag,
                        tmp_path)
    if role in ("input_file", "output_file"):
        wrong = tmp_path / f"a_folder{SUFFIX.get(flag, SUFFIX.get(command, '.json'))}"
        if role == "input_file":
            wrong = tmp_path / "a_folder.csv"
        wrong.mkdir()
        (wrong / "inside.txt").write_text("mine")
    else:
        wrong = tmp_path / "a_file.txt"
        wrong.write_text("mine")
    args = _with(command, tmp_path, flag, str(wrong))
    if "--overwrite" in {p.opts[0] for p in COMMANDS[command].params}:
        args.append("--overwrite")
    _assert_refused(args, flag, tmp_path)
    assert (wrong / "inside.txt" if wrong.is_dir() else wrong).read_text() == "mine"


def test_a_bad_value_leaves_an_existing_folder_as_it_was(tmp_path):
    out = tmp_path / "kept"
    out.mkdir()
    (out / "note.txt").write_text("mine")
    code, err = _run(["simulate", "--out", str(out), "--seconds", "5", "--head-speed", "50"])
    assert code == 2 and "top speed" in err
    assert err.startswith("error: --head-speed: ")      # the library names head_speed
    assert [p.name for p in out.iterdir()] == ["note.txt"]


def test_a_library_error_names_the_commands_flag(tmp_path):
    """The library names its parameter (`n`, `seeds`); the CLI names its own flag for it."""
    for args, flag in ((["simulate", "--robots", "400"], "--robots"),
                       (["soak", "--scenario", "lab", "--robots", "400"], "--robots")):
        code, err = _run([*args, "--out", str(tmp_path / "out")])
        assert code == 2 and err.startswith(f"error: {flag}: "), err
        assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("args", [
    ["simulate", "--seconds", "5", "--head-speed", "50"],          # past the robot's top speed
    ["collect", "--minutes", "1", "--split", "50/10/10"],          # does not sum to 100
    ["collect", "--minutes", "1", "--episode-minutes", "0.1"],     # names the right option
])
def test_library_checks_after_parsing_leave_nothing_behind(tmp_path, args):
    out = tmp_path / "out"
    code, err = _run([*args, "--out", str(out)])
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert not out.exists()
    if "--episode-minutes" in args:
        assert err.startswith("error: --episode-minutes 0.1"), err


def test_the_command_line_starts_without_torch():
    """Every command imports its heavy dependencies lazily: `--help` or a fetch that has
    nothing to do should not pay torch's two seconds of import."""
    import subprocess
    import sys

    code = ("import sys\nfrom macrostate_mj.app.cli import app  # noqa: F401\n"
            "print(sorted(m for m in ('torch', 'mujoco', 'cv2') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert "torch" not in out, out
