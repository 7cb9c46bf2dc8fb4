"""`data fetch`: the published real datasets, pinned by sha256, into the reference-data root."""

from __future__ import annotations

import os
from pathlib import Path

import typer

from macrostate_mj.app.cli.app import data_app
from macrostate_mj.app.params import DatasetNames, OutputDir


@data_app.command("fetch")
def data_fetch(
    names: list[str] = DatasetNames(),
    folder: Path = OutputDir(None, "The reference-data root to fetch into (default: "
                             "$MACROSTATE_DATA_CACHE, else the user's cache folder, which the "
                             "real-data commands read by default).", "--dir"),
    mirror: str = typer.Option(None, "--mirror", help="A base URL under which the files sit "
                               "at their paths in the publishing repository, the ant flows as "
                               "archive/<commit>.zip (default: the pinned commit on GitHub)."),
) -> None:
    """Download each dataset unless present and verified, check it against the pinned sha256
    (per file, or per folder for the ant flows' archive), and say where it is. The held-out
    test files come too: never train, tune or report on them."""
    from macrostate_mj.core.datasets import cache_root, fetch, named
    from macrostate_mj.core.progress import live

    chosen = named(names)
    root = folder if folder is not None else cache_root()
    for dataset in chosen:
        count = fetch(dataset, root, mirror, progress=live())
        print(f"{dataset.name:<10} {count} files verified in {root / dataset.folder} "
              f"({dataset.repo}@{dataset.commit[:7]})")
    if folder is not None:
        print(f"read them with MACROSTATE_REFERENCE_DATA={root}")
    elif os.environ.get("MACROSTATE_REFERENCE_DATA"):
        print("MACROSTATE_REFERENCE_DATA is set, so commands read that folder, not these")
