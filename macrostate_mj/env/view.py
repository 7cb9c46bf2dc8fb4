"""The overhead camera's view of a task, for the single-agent and team environments alike:
rendered lazily on the first `render()`, released on `close()`."""

from __future__ import annotations

from typing import Any

import numpy as np


class OverheadView:
    """A mixin: `render()` and `close()` for an environment holding `task` and `render_mode`."""

    task: Any
    render_mode: str | None
    _renderer: Any = None

    def render(self) -> np.ndarray | None:
        if self.render_mode != "rgb_array":
            return None
        from macrostate_mj.vision.camera import OverheadRenderer

        if self._renderer is None:
            self._renderer = OverheadRenderer(self.task.sim.model)
        return self._renderer.render(self.task.sim.data)

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        self.task.close()
