"""The one way figures are saved: PNG written atomically, with no creation metadata, so that a
rerun gives a byte-identical file."""

from __future__ import annotations

import os

from macrostate_mj.core.io import atomic_path


def save_png(fig, path: str | os.PathLike, dpi: int = 120, tight: bool = False) -> None:
    import matplotlib.pyplot as plt

    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=dpi, metadata={"Software": None},
                    **({"bbox_inches": "tight"} if tight else {}))
    plt.close(fig)
