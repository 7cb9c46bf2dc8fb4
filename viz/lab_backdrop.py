"""Fig 2.9's camera view: the lab scene rendered by its overhead camera with the robots posed
from ThymioLoc pixels, the backdrop `viz.retlo_figures.write_video` draws estimates on."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from macrostate_mj.formats.thymioloc import DEFAULT_PX_PER_CM


class LabBackdrop:
    """The lab scene rendered by its overhead camera with the robots at given ThymioLoc poses.
    The lab camera frames the 2.5 x 1.9 m arena at 3 px/cm, so its pixels are ThymioLoc pixels
    (real or collected); other scales get no backdrop."""

    def __init__(self, n_robots: int, px_per_cm: float):
        import mujoco

        from macrostate_mj.chain.scenarios import SCENARIOS
        from macrostate_mj.chain.world import build_world
        from macrostate_mj.vision.camera import OverheadRenderer

        self.cfg = SCENARIOS["lab"]        # the built-in lab: ThymioLoc's own arena
        self.world = build_world(self.cfg, n_robots)
        self.data = mujoco.MjData(self.world.model)
        self.renderer = OverheadRenderer(self.world.model)
        self.px_per_cm = px_per_cm
        self.size = (self.renderer.width, self.renderer.height)
        self.colours_bgr = [tuple(int(c) for c in rgb[::-1] * 255) for rgb in self.world.colours]

    def fits(self, px: np.ndarray) -> bool:
        """Do poses px (..., N, 3) lie in this camera's frame at its scale?"""
        return (abs(self.px_per_cm - DEFAULT_PX_PER_CM) < 1e-9 and np.nanmin(px[..., :2]) >= 0
                and all(np.nanmax(px[..., i]) < self.size[i] for i in (0, 1)))

    def __call__(self, px: np.ndarray) -> np.ndarray:
        """BGR camera frame with robot i at ThymioLoc pose px[i] (x px, y px, o deg)."""
        import mujoco

        from macrostate_mj.formats.instances import from_thymioloc_pixels

        model, data = self.world.model, self.data
        for adr, (x, y, th) in zip(self.world.qpos_adr,
                                   from_thymioloc_pixels(px, self.cfg.arena, self.px_per_cm),
                                   strict=True):
            data.qpos[adr:adr + 3] = [x, y, model.qpos0[adr + 2]]
            data.qpos[adr + 3:adr + 7] = [np.cos(th / 2), 0, 0, np.sin(th / 2)]
        mujoco.mj_forward(model, data)
        return np.ascontiguousarray(self.renderer.render(data)[:, :, ::-1])

    def __enter__(self) -> LabBackdrop:
        return self

    def __exit__(self, *exc: object) -> None:
        self.renderer.close()


def write_lab_video(path: Path, true_px: np.ndarray, est_px: np.ndarray, px_per_cm: float
                    ) -> Path:
    """Fig 2.9 over the lab camera's view where the poses fit its frame, else over a plain
    floor (`viz.retlo_figures.write_video`; arrays as it takes them)."""
    from viz.retlo_figures import write_video

    with LabBackdrop(true_px.shape[2], px_per_cm) as backdrop:
        fits = backdrop.fits(true_px)
        return write_video(path, true_px, est_px, px_per_cm,
                           backdrop=backdrop if fits else None, frame_size=backdrop.size,
                           colours=backdrop.colours_bgr if fits else None)
