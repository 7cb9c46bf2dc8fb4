"""`soak` as a use case: many seeds of one scenario, as physics runs or tracked runs, under a
run in `out` when one is given (a rerun resumes from the finished seeds); the summary row, and
the failure that names the first bad seed and the command that reproduces it."""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from pathlib import Path

from macrostate_mj.chain.scenario import ScenarioConfig
from macrostate_mj.core.errors import RunFailure


def soak(scenario: ScenarioConfig, robots: int, seeds: int, seconds: float, first_seed: int,
         workers: int, ray: str | None, check_hz: float, out: Path | None, track: bool,
         overwrite: bool, bar: Callable[..., None] | None = None) -> tuple[dict, list]:
    """The summary row and every seed's run (in seed order); `bar(done, cached)` follows them."""
    from macrostate_mj.chain.soak import run_records, soak_tasks, summary
    from macrostate_mj.chain.soak import soak as run_soak
    from macrostate_mj.core.cache import TaskCache
    from macrostate_mj.core.io import write_json_atomic
    from macrostate_mj.core.run import Run

    tasks = soak_tasks(scenario, robots, seeds, seconds, first_seed, check_hz)
    if track:
        from collectors.track_soak import TrackSoakTask, track_summary
        from macrostate_mj.chain.filmed import check_filmed

        check_filmed(scenario, robots)      # refused before any run, as simulate does
        kind, tabulate = TrackSoakTask, track_summary
    else:
        kind, tabulate = None, lambda runs: summary(runs, workers)
    with contextlib.ExitStack() as stack:
        config = {"tasks": tasks[0], "seeds": seeds, **({"track": True} if track else {})}
        run = None if out is None else stack.enter_context(
            Run(out, "soak", config, first_seed, ["soak.json"], overwrite))
        runs = run_soak(tasks, workers, ray, bar, None if out is None
                        else TaskCache(out / "cache"), **({"kind": kind} if kind else {}))
        row = {"scenario": scenario.name, "robots": robots, "seconds": seconds,
               **tabulate(runs)}
        if run is not None:
            write_json_atomic(out / "soak.json", {"summary": row, "runs": run_records(runs)})
            run.record(workers=workers, outputs={"soak": str(out / "soak.json")})
    return row, runs


def check(runs: list, scenario: ScenarioConfig, robots: int, seconds: float,
          track: bool) -> None:
    """A `RunFailure` naming the first unhealthy (tracked) or faulted seed, with the
    `simulate` command that reproduces it; nothing when every run was sound."""
    from macrostate_mj.app.simulate import SimulateRequest, reproduce_command

    failures = (([r for r in runs if r.findings] if track else []), "tracked unhealthily",
                lambda r: r.findings[0], track), \
               ([r for r in runs if r.fault is not None], "faulted", lambda r: r.reason, False)
    for failed, what, reason, tracked in failures:
        if failed:
            first = failed[0].seed
            again = SimulateRequest(scenario, robots, seconds, first, Path(f"soak_seed{first}"),
                                    track=tracked)
            raise RunFailure(f"{len(failed)} of {len(runs)} runs {what}; first: seed {first}: "
                             f"{reason(failed[0])}; reproduce: {reproduce_command(again)}")
