"""`scenario show` and `scenario check`: what a scenario file resolves to and what it builds."""

from __future__ import annotations

import typer

from macrostate_mj.app.cli.app import app
from macrostate_mj.app.cli.params import ScenarioArg

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
    """Validate a scenario and print what it builds: arena, chain capacity, px/cm, timestep and
    physics steps per command and log tick."""
    import math

    from macrostate_mj.chain.robot import top_speed
    from macrostate_mj.chain.scenario import steps_per_tick
    from macrostate_mj.chain.world import build_world, chain_capacity

    cfg = scenario
    capacity = chain_capacity(cfg)
    build_world(cfg, min(capacity, 3))           # the robot file meets its contract
    dt = cfg.physics.timestep
    w, h = cfg.camera.resolution
    fovy = cfg.camera.fovy_for(cfg.arena)
    px_per_m = h / 2 / math.tan(math.radians(fovy) / 2) / cfg.camera.height
    walls = "walls" if cfg.walls is not None else "no walls"
    typer.echo(f"scenario   {cfg.name}: robot {cfg.robot}, arena {cfg.arena[0]:g} x "
               f"{cfg.arena[1]:g} m ({walls})")
    typer.echo(f"chain      up to {capacity} robots at spacing {cfg.spacing:g} m; Head "
               f"{cfg.head_speed:g} m/s (robot's top {top_speed(cfg.robot):.3f} m/s)")
    typer.echo(f"camera     {w} x {h} px at {cfg.camera.height:g} m, fovy {fovy:.2f} deg: "
               f"{px_per_m / 100:.2f} px/cm")
    typer.echo(f"physics    timestep {dt:g} s: {steps_per_tick(1 / cfg.command_hz, dt, 'command')}"
               f" steps a command tick ({cfg.command_hz:g} Hz), "
               f"{steps_per_tick(1 / cfg.log_hz, dt, 'log')} a log tick ({cfg.log_hz:g} Hz)")
