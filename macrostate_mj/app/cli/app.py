"""The Typer application and its command groups; commands register themselves in sibling modules."""

import typer

from macrostate_mj import __version__

app = typer.Typer(
    name="macrostate-mj",
    help="MuJoCo testbed for inferring a collective's macrostate from one member or one camera.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=False,
)
train_app = typer.Typer(help="Train an estimator.", no_args_is_help=True)
evaluate_app = typer.Typer(help="Evaluate a trained estimator.", no_args_is_help=True)
ants_app = typer.Typer(help="Simulated ant colony.", no_args_is_help=True)
calibrate_app = typer.Typer(help="Refit a trained estimator's uncertainty on other data.",
                            no_args_is_help=True)
oc_app = typer.Typer(help="One-class models on optical flows (IO-GEN and baselines).",
                     no_args_is_help=True)
data_app = typer.Typer(help="The published real datasets: fetch and verify them.",
                       no_args_is_help=True)

app.add_typer(train_app, name="train")
app.add_typer(evaluate_app, name="evaluate")
app.add_typer(calibrate_app, name="calibrate")
app.add_typer(ants_app, name="ants")
app.add_typer(oc_app, name="oc")
app.add_typer(data_app, name="data")


def _print_version(value: bool) -> None:
    if value:
        print(f"macrostate-mj {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    version: bool = typer.Option(False, "--version", callback=_print_version, is_eager=True,
                                 help="Print the version and exit."),
    quiet: bool = typer.Option(False, "--quiet/--verbose", "-q",
                               help="No progress bars or progress lines (results and errors "
                               "still print); goes before the command."),
) -> None:
    """MuJoCo testbed for inferring a collective's macrostate from one member or one camera."""
    from macrostate_mj.core.progress import set_quiet

    set_quiet(quiet)
