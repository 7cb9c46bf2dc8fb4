"""`scenario show` and `scenario check`: what a scenario file resolves to and what it builds."""

from __future__ import annotations

from dataclasses import fields
from typing import TYPE_CHECKING

import typer

from macrostate_mj.app.cli.app import app
from macrostate_mj.app.params import ScenarioArg

if TYPE_CHECKING:
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
    centre and worst arena corner, the lens, the markers, the obstacles, the robot's colours as
    rendered, timestep and physics steps per command and log tick."""
    from macrostate_mj.chain.markers import ColourMarkers
    from macrostate_mj.chain.rendered import check_rendered_colours
    from macrostate_mj.chain.robot import top_speed
    from macrostate_mj.chain.scenario import steps_per_tick
    from macrostate_mj.chain.world import build_world, chain_capacity

    cfg = scenario
    capacity = chain_capacity(cfg)
    build_world(cfg, min(capacity, 3))           # the robot file meets its contract
    teams = _team_sizes(cfg, capacity)
    for n in teams:
        check_rendered_colours(cfg, n)           # no part passes for a marker as filmed
    dt = cfg.physics.timestep
    walls = "walls" if cfg.walls is not None else "no walls"
    typer.echo(f"scenario   {cfg.name}: robot {cfg.robot}, arena {cfg.arena[0]:g} x "
               f"{cfg.arena[1]:g} m ({walls})")
    typer.echo(f"chain      up to {capacity} robots at spacing {cfg.spacing:g} m; Head "
               f"{cfg.head_speed:g} m/s (robot's top {top_speed(cfg.robot):.3f} m/s)")
    typer.echo(_camera_line(cfg))
    typer.echo(_lens_line(cfg.camera.distortion))
    checked = (f"robot parts as rendered taken for no marker ({_teams_words(teams)})"
               if isinstance(cfg.markers, ColourMarkers) else "tags: no colours to check")
    typer.echo(f"markers    {_markers_kind(cfg.markers)}; {checked}")
    typer.echo(_obstacles_line(cfg.obstacles))
    typer.echo(f"physics    timestep {dt:g} s: {steps_per_tick(1 / cfg.command_hz, dt, 'command')}"
               f" steps a command tick ({cfg.command_hz:g} Hz), "
               f"{steps_per_tick(1 / cfg.log_hz, dt, 'log')} a log tick ({cfg.log_hz:g} Hz)")


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
