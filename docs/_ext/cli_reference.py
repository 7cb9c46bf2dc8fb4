"""The CLI reference, generated from the typer app: ``{cli-reference}`` renders every command
with its help, usage and options. sphinx-click cannot read this app: typer 0.29 vendors its own
click, whose commands are not `click.Command` instances."""

from __future__ import annotations

from docutils import nodes
from docutils.parsers.rst import Directive

from results import table_node


def _commands(command: object, path: list[str]) -> list[tuple[list[str], object]]:
    """Every leaf command under `command`, with its path of names, in the app's order."""
    children = getattr(command, "commands", None)
    if not children:
        return [(path, command)]
    found: list[tuple[list[str], object]] = []
    for name, child in children.items():
        if not getattr(child, "hidden", False):
            found += _commands(child, [*path, name])
    return found


def _default(param: object) -> str:
    """As `--help` shows it: required, or the default (0 and false included)."""
    if getattr(param, "required", False):
        return "required"
    default = getattr(param, "default", None)
    if default is None or default in ((), []):
        return ""
    return str(default).lower() if isinstance(default, bool) else str(default)


class CliReference(Directive):
    """Every command of `macrostate-mj`, a section each."""

    def run(self) -> list[nodes.Node]:
        import typer

        from macrostate_mj.app.cli import app

        root = typer.main.get_command(app)
        sections = []
        for path, command in _commands(root, []):
            name = " ".join(path)
            section = nodes.section(ids=[nodes.make_id("cli-" + name)])
            section += nodes.title(text=f"macrostate-mj {name}")
            help_text = (command.help or "").strip()
            for paragraph in filter(None, (p.strip() for p in help_text.split("\n\n"))):
                section += nodes.paragraph(text=" ".join(paragraph.split()))
            rows = [["option", "help", "default"]]
            for param in command.params:
                opts = ", ".join([*param.opts, *getattr(param, "secondary_opts", [])])
                if type(param).__name__.endswith("Argument"):
                    opts = param.name.upper()
                rows.append([opts, " ".join((getattr(param, "help", "") or "").split()),
                             _default(param)])
            if len(rows) > 1:
                section += table_node(rows)
            sections.append(section)
        return sections




# What each scenario-file key means; `{scenario-keys}` fails the build on a key missing here.
MEANINGS = {
    "name": "the scenario's name, recorded in manifests",
    "extends": "a built-in's name or another file this one overrides",
    "arena.size": "[x, y] floor size, m",
    "arena.margin": "distance waypoints and start poses keep from walls and obstacles, m",
    "arena.obstacles": ("[{shape = box | cylinder, pos = [x, y], size = ...}], full extents in "
                        "m: a box [x, y] or [x, y, height], a cylinder [diameter] or "
                        "[diameter, height]; height 0.1 m unless given"),
    "arena.walls": "walls on the arena's edges (false: an open floor)",
    "arena.wall_height": "m", "arena.wall_thickness": "m",
    "robot.model": "thymio, gritsbot, epuck, or a robot.xml path (its contract: Robot contract)",
    "chain.spacing": "follow distance d, m",
    "chain.head_speed": "the Head's cruise speed, m/s, at most the robot's top speed",
    "chain.chain_speed": "the Followers' and Tail's speed cap, m/s",
    "chain.k_f": "Follower gain", "chain.k_t": "Tail gain", "chain.k_omega": "heading gain",
    "chain.allow_reverse": "whether robots may drive backwards",
    "chain.reach_radius": "a waypoint counts as reached within it, m",
    "chain.avoid_radius": "robots repel each other within it, m",
    "chain.avoid_gain": "strength of that repulsion",
    "chain.head_turn_speed": "the share of its speed the Head keeps while turning toward a "
                             "waypoint under 90 degrees off (0: slows by the cosine, as the "
                             "text's tracking; 1: full speed)",
    "rates.command_hz": "control and camera rate, Hz", "rates.log_hz": "pose log rate, Hz",
    "rates.frame_hz": "the camera's frame rate, Hz (auto: the command rate)",
    "rates.frame_jitter": "each frame's delay after its nominal instant, uniform up to it, s",
    "rates.frame_alternation": "the frames every other log row reads taken this much earlier, s",
    "robot.wheel_spread": "each wheel's effective radius factor 1 + N(0, spread), drawn per "
                          "episode",
    "noise.marker_offset": "each robot's marker off its centre, m (σ per body axis, per "
                           "episode)",
    "noise.marker_jitter": "white noise added to every tracked position, m (σ)",
    "noise.head_jitter_scale": "the Head's marker jitter as a share of marker_jitter",
    "noise.light_scale": "[low, high] of the diffuse light's intensity factor, drawn per episode",
    "noise.light_tilt_deg": "largest tilt of the key light from vertical, degrees",
    "noise.cam_shift_m": "camera position error the tracker's calibration does not know, m (σ)",
    "noise.cam_tilt_deg": "camera orientation error the calibration does not know, degrees (σ)",
    "noise.sensor_sigma": "Gaussian sensor noise, 0-255 units (σ)",
    "noise.jpeg_quality": "[low, high] JPEG quality, drawn per episode",
    "noise.blur_px": "longest motion blur, px",
    "noise.psf_sigma_px": "the lens's point-spread function, px (σ)",
    "noise.drop_prob": "probability a whole frame is lost",
    "noise.distortion_error": "the calibrated k1, k2's relative error (σ), drawn per episode",
    "camera.height": "m above the floor's centre, looking straight down",
    "camera.resolution": "[w, h] pixels",
    "camera.fovy": "vertical field of view, degrees, or \"auto\" to frame the arena",
    "camera.distortion": "the lens, OpenCV's [k1, k2, p1, p2]",
    "physics.timestep": "s; must divide the command and log periods into whole steps",
    "physics.integrator": "MuJoCo integrator (implicitfast, euler, rk4, implicit)",
    "physics.impratio": "MuJoCo's frictional-to-normal impedance ratio",
    "physics.cone": "friction cone (elliptic or pyramidal)",
    "look.floor_rgba": "floor colour", "look.wall_rgba": "wall colour",
    "look.light_height": "m", "look.light_diffuse": "0-1",
    "look.headlight_ambient": "0-1", "look.headlight_diffuse": "0-1",
    "planner.kind": "the Head's planner: psi_grid (the lab's cell walk), cell_walk, "
                    "preset_twists, or park (drive to planner.point and stay)",
    "planner.point": "park: where the Head parks, [x, y] m (driven to straight: an obstacle "
                     "in the way stops it there)",
    "planner.grid": "[columns, rows] of the planner's grid",
    "planner.max_turn": "psi_grid: the largest turn toward the Head's next waypoint, degrees "
                        "(180: Psi as written)",
    "planner.presets": "the Head's (v, ω) schedule of the preset planner",
    "followers.kind": "follower rule: two_neighbours or wait_for_behind",
    "followers.slack": "wait while the robot behind lags more than d + slack, m",
    "followers.hold": "stop, not back off, while less than this nearer than d to the robot "
                      "ahead, m (0: back off; d: never)",
    "followers.start": "wait until the robot ahead is more than d + start away, m",
    "markers.kind": "what each robot wears: colour (a triangle of its own colour) or aruco "
                    "(a fiducial tag, with markers.dictionary)",
    "markers.dictionary": "aruco: OpenCV's predefined dictionary, e.g. DICT_4X4_50",
    "tracking.min_detected": "a tracked run fails when a robot is detected in fewer of the "
                             "dataset's rows where it is in view (share)",
    "tracking.max_hidden": "... or an obstacle or wall hides it from the camera in more of "
                           "the rows (share)",
    "tracking.max_median_mm": "... or it is tracked farther from the truth at the median (mm)",
    "tracking.max_p99_mm": "... or at the 99th percentile (mm)",
    "tracking.max_heading_off30": "... or its heading errs by more than 30 degrees in more of "
                                  "its detections (share)",
    "tracking.max_heading_flips": "... or by more than 90 degrees, flipped (share)",
    "tracking.max_identity_errors": "... or its detections lie nearer another robot's truth "
                                    "in more of them (share)",
}


def _flat(table: dict, prefix: str = "") -> dict[str, object]:
    out: dict[str, object] = {}
    for key, value in table.items():
        if isinstance(value, dict):
            out |= _flat(value, f"{prefix}{key}.")
        else:
            out[f"{prefix}{key}"] = value
    return out


class ScenarioKeys(Directive):
    """Every key `scenario show` writes, with each built-in's value."""

    def run(self) -> list[nodes.Node]:
        import tomllib

        from macrostate_mj.chain.scenario_file import to_toml
        from macrostate_mj.chain.scenarios import SCENARIOS

        flat = {name: _flat(tomllib.loads(to_toml(cfg))) for name, cfg in SCENARIOS.items()}
        keys = list(dict.fromkeys(k for table in flat.values() for k in table))
        missing = [k for k in keys if k not in MEANINGS]
        if missing:
            raise self.error(f"scenario keys without a meaning in cli_reference.py: {missing}")
        rows = [["key", "meaning", *flat]]
        for key in keys:
            rows.append([key, MEANINGS[key], *[_show(t.get(key, "")) for t in flat.values()]])
        return [table_node(rows)]


def _show(value: object) -> str:
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, str):
        return value
    return str(value).replace("'", "")


def setup(app: object) -> dict:
    app.add_directive("cli-reference", CliReference)  # type: ignore[attr-defined]
    app.add_directive("scenario-keys", ScenarioKeys)  # type: ignore[attr-defined]
    return {"parallel_read_safe": True, "version": "1"}
