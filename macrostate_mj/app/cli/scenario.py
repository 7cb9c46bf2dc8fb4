"""`scenario show` and `scenario check`: what a scenario file resolves to and what it builds."""

from __future__ import annotations

from dataclasses import fields
from typing import TYPE_CHECKING

import typer

from macrostate_mj.app.cli.app import app
from macrostate_mj.app.params import ScenarioArg

if TYPE_CHECKING:
    from macrostate_mj.chain.filmed import TagCells
    from macrostate_mj.chain.scenario import ScenarioConfig
    from macrostate_mj.chain.scene import Obstacle

scenario_app = typer.Typer(help="Scenario files: print one resolved, check one.",
                           no_args_is_help=True)
app.add_typer(scenario_app, name="scenario")


@scenario_app.command("show")
def scenario_show(
    scenario: str = ScenarioArg(),
) -> None:
    """Print the scenario resolved (its `extends` merged in) as a scenario file."""
    from macrostate_mj.chain.scenario_file import to_toml

    typer.echo(to_toml(scenario), nl=False)


@scenario_app.command("check")
def scenario_check(
    scenario: str = ScenarioArg(),
) -> None:
    """Validate a scenario and print what it builds: arena, chain capacity, px/cm at the image's
    centre and worst arena corner, the lens, the markers, the obstacles, timestep and physics
    steps per command and log tick, the `[tracking]` limits. What a tracked run refuses up front
    (`chain.filmed`) is refused here for every team size: a surface or robot part that passes
    for a colour marker as rendered, tags too narrow in pixels for the detector."""
    from macrostate_mj.chain.filmed import check_tag_cells
    from macrostate_mj.chain.rendered import check_rendered_colours
    from macrostate_mj.chain.robot import top_speed
    from macrostate_mj.chain.scenario import steps_per_tick
    from macrostate_mj.chain.world import build_world, chain_capacity

    cfg = scenario
    capacity = chain_capacity(cfg)
    build_world(cfg, min(capacity, 3))           # the robot file meets its contract
    teams = _team_sizes(cfg, capacity)
    for n in teams:
        check_rendered_colours(cfg, n)           # nothing in view passes for a marker as filmed
    cells = check_tag_cells(cfg)                 # tags wide enough for the detector
    dt = cfg.physics.timestep
    walls = "walls" if cfg.walls is not None else "no walls"
    typer.echo(f"scenario   {cfg.name}: robot {cfg.robot}, arena {cfg.arena[0]:g} x "
               f"{cfg.arena[1]:g} m ({walls})")
    typer.echo(f"chain      up to {capacity} robots at spacing {cfg.spacing:g} m; Head "
               f"{cfg.head_speed:g} m/s (robot's top {top_speed(cfg.robot):.3f} m/s)")
    typer.echo(_camera_line(cfg))
    typer.echo(_lens_line(cfg.camera.distortion))
    typer.echo(f"markers    {_markers_kind(cfg.markers)}; {_checked_words(cfg, cells, teams)}")
    typer.echo(_obstacles_line(cfg.obstacles))
    typer.echo(f"physics    timestep {dt:g} s: {steps_per_tick(1 / cfg.command_hz, dt, 'command')}"
               f" steps a command tick ({cfg.command_hz:g} Hz), "
               f"{steps_per_tick(1 / cfg.log_hz, dt, 'log')} a log tick ({cfg.log_hz:g} Hz)")
    typer.echo(f"tracking   limits: {cfg.tracking.describe()}")


def _team_sizes(cfg: ScenarioConfig, capacity: int) -> list[int]:
    """The team sizes a world of this scenario can have: 2 to its capacity, less those its
    marker kind refuses (where it can refuse any)."""
    from macrostate_mj.core.errors import UserError

    check = getattr(cfg.markers, "check_team", None)
    teams = []
    for n in range(2, capacity + 1):
        try:
            if check is not None:
                check(n)
        except UserError:
            continue
        teams.append(n)
    return teams


def _teams_words(teams: list[int]) -> str:
    if not teams:
        return "no team fits"
    return f"team of {teams[0]}" if len(teams) == 1 else f"teams of {teams[0]}-{teams[-1]}"


def _checked_words(cfg: ScenarioConfig, cells: TagCells | None, teams: list[int]) -> str:
    """What the markers' check judged: what in view no colour marker is taken for, or the
    tags' cells."""
    from macrostate_mj.chain.filmed import MIN_TAG_CELL_PX

    if cells is None:
        seen = ["floor", *(["walls"] if cfg.walls is not None else []),
                *(["obstacles"] if cfg.obstacles else [])]
        return (f"{', '.join(seen)} and robot parts as rendered taken for no marker "
                f"({_teams_words(teams)})")
    return (f"tag cells {cells.centre:.2f} px at the centre, {cells.worst:.2f} px at the "
            f"{cells.corner} corner (the detector needs {MIN_TAG_CELL_PX:g} px)")


def _camera_line(cfg: ScenarioConfig) -> str:
    """Resolution, height, fovy and px/cm at the image's centre and at the arena corner the
    image resolves worst (the lens squeezes or stretches the corners)."""
    from macrostate_mj.chain.scene import CORNERS

    cam = cfg.camera
    w, h = cam.resolution
    corners = [[sx * cfg.arena[0] / 2, sy * cfg.arena[1] / 2] for sx, sy in CORNERS.values()]
    scale = cam.px_per_m_at(cfg.arena, [[0.0, 0.0], *corners]) / 100
    worst = int(scale[1:].argmin())
    return (f"camera     {w} x {h} px at {cam.height:g} m, fovy {cam.fovy_for(cfg.arena):.2f} "
            f"deg: {scale[0]:.2f} px/cm at the centre, {scale[1 + worst]:.2f} px/cm at the "
            f"{list(CORNERS)[worst]} corner")


def _lens_line(distortion: tuple[float, float, float, float]) -> str:
    from macrostate_mj.chain.scene import lens_words

    return f"lens       {lens_words(distortion) if any(distortion) else 'ideal (pinhole)'}"


def _markers_kind(markers: object) -> str:
    """The marker kind as a scenario file names it (`[markers] kind`), and its settings."""
    from macrostate_mj.chain import scenario_file

    kinds = scenario_file.RULES["markers"]
    kind = next((k for k, c in kinds.items() if type(markers) is c), type(markers).__name__)
    settings = ", ".join(f"{f.name} {getattr(markers, f.name)}" for f in fields(markers))
    return f"{kind}" + (f" ({settings})" if settings else "")


def _obstacles_line(obstacles: tuple[Obstacle, ...]) -> str:
    if not obstacles:
        return "obstacles  none"
    each = "; ".join(f"{ob.shape} {' x '.join(f'{v:g}' for v in ob.size)} m at "
                     f"({ob.pos[0]:g}, {ob.pos[1]:g})" for ob in obstacles)
    return f"obstacles  {len(obstacles)}: {each}"
