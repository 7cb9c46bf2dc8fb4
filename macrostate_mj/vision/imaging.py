"""Imaging noise between the renderer and the tracker: the camera chain of the real testbed.

Domain randomization per episode (light intensity and direction, a small camera-pose error
the tracker's calibration does not know about, an error in its calibrated lens distortion,
JPEG quality, motion-blur direction), and per frame (sensor noise, blur, compression, dropped
frames). Every draw comes from the Generator passed in. Defaults aim at the real camera:
sub-pixel to one-pixel tracking error, rare drops.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import cv2
import mujoco
import numpy as np

from macrostate_mj.chain.noise import NoiseConfig as NoiseConfig  # the scenario's; re-exported


@dataclass(frozen=True)
class EpisodeImaging:
    """One episode's draw of the randomized conditions."""

    light_scale: float
    light_dir: np.ndarray
    cam_shift: np.ndarray
    cam_rot: np.ndarray          # quaternion (w, x, y, z) applied to the nominal camera
    jpeg_quality: int
    blur_kernel: np.ndarray | None    # this episode's motion blur
    psf: np.ndarray | None            # the lens's separable point-spread function
    sensor_field: SensorField | None  # FIELD_MARGIN px larger than the frame
    # The tracker's calibrated lens: k1, k2 of the scenario's lens times these (1 + error).
    distortion_scale: tuple[float, float] = (1.0, 1.0)

    def calibrated(self, distortion: tuple[float, float, float, float]
                   ) -> tuple[float, float, float, float]:
        """The tracker's belief about the lens `distortion`: as the camera-pose error, a
        calibration off by this episode's draw."""
        k1, k2, p1, p2 = distortion
        return (k1 * self.distortion_scale[0], k2 * self.distortion_scale[1], p1, p2)


FIELD_MARGIN = 48


@dataclass(frozen=True)
class SensorField:
    """Integer sensor noise split into its positive and negative parts (uint8): adding one
    and subtracting the other, both saturating, gives exactly clip(frame + noise) at a
    quarter of the cost of an int16 add with conversion."""

    plus: np.ndarray
    minus: np.ndarray

    @classmethod
    def of(cls, noise: np.ndarray) -> SensorField:
        return cls(np.clip(noise, 0, 255).astype(np.uint8),
                   np.clip(-noise, 0, 255).astype(np.uint8))

    def add_to(self, img: np.ndarray, dy: int, dx: int) -> np.ndarray:
        h, w = img.shape[:2]
        return cv2.subtract(cv2.add(img, self.plus[dy:dy + h, dx:dx + w]),
                            self.minus[dy:dy + h, dx:dx + w])


def draw_episode(cfg: NoiseConfig, rng: np.random.Generator,
                 frame_shape: tuple[int, int, int] = (570, 750, 3)) -> EpisodeImaging:
    """Draw one episode's conditions. Sensor noise is drawn once as a field a little larger
    than the frame; each frame takes a random crop of it (new noise at every pixel, at a
    fraction of the cost of fresh Gaussian draws for 1.3 M values per frame)."""
    tilt = np.radians(rng.uniform(0, cfg.light_tilt_deg))
    az = rng.uniform(-np.pi, np.pi)
    light_dir = np.array([np.sin(tilt) * np.cos(az), np.sin(tilt) * np.sin(az), -np.cos(tilt)])
    axis_angle = np.radians(cfg.cam_tilt_deg) * rng.standard_normal(3)
    quat = np.zeros(4)
    mujoco.mju_axisAngle2Quat(quat, axis_angle / max(np.linalg.norm(axis_angle), 1e-12),
                              float(np.linalg.norm(axis_angle)))
    length = rng.uniform(0, cfg.blur_px)
    kernel = _line_kernel(length, rng.uniform(0, np.pi)) if length >= 0.5 else None
    lo, hi = cfg.jpeg_quality
    field = None
    if cfg.sensor_sigma > 0:
        h, w, c = frame_shape
        field = SensorField.of(np.round(rng.normal(
            0.0, cfg.sensor_sigma, (h + FIELD_MARGIN, w + FIELD_MARGIN, c))).astype(np.int16))
    ep = EpisodeImaging(float(rng.uniform(*cfg.light_scale)), light_dir,
                        cfg.cam_shift_m * rng.standard_normal(3), quat,
                        int(rng.integers(lo, hi + 1)), kernel, lens_psf(cfg.psf_sigma_px), field)
    if cfg.distortion_error > 0:      # drawn last and only then: error-free streams unchanged
        scale = 1 + cfg.distortion_error * rng.standard_normal(2)
        ep = replace(ep, distortion_scale=(float(scale[0]), float(scale[1])))
    return ep


def _line_kernel(length: float, angle: float) -> np.ndarray:
    """A normalized line kernel of `length` px at `angle`: linear motion during exposure."""
    size = int(np.ceil(length)) * 2 + 1
    k = np.zeros((size, size), np.float32)
    c = size // 2
    for s in np.linspace(-length / 2, length / 2, 4 * size):
        k[int(round(c + s * np.sin(angle))), int(round(c + s * np.cos(angle)))] += 1
    return k / k.sum()


def lens_psf(sigma: float) -> np.ndarray | None:
    """The lens as a separable Gaussian point-spread function (1-D taps, applied along both
    axes). The renderer does no anti-aliasing (`offsamples="0"`, 3.5x cheaper): a real camera's
    edges are softened by its lens instead. Taps beyond 2.5 sigma weigh under 1e-5 and go."""
    if sigma <= 0:
        return None
    r = max(1, int(np.ceil(2.5 * sigma)))
    return cv2.getGaussianKernel(2 * r + 1, sigma, cv2.CV_32F)


class SceneConditions:
    """Applies an episode's light and camera draw to a model, restoring nominal values first."""

    def __init__(self, model: mujoco.MjModel, camera: str = "overhead"):
        self.model = model
        self.cam = model.camera(camera).id
        self._light_diffuse = model.light_diffuse.copy()
        self._light_dir = model.light_dir.copy()
        self._cam_pos = model.cam_pos[self.cam].copy()
        self._cam_quat = model.cam_quat[self.cam].copy()

    def apply(self, ep: EpisodeImaging) -> None:
        m = self.model
        m.light_diffuse[:] = np.clip(self._light_diffuse * ep.light_scale, 0, 1)
        m.light_dir[:] = ep.light_dir
        m.cam_pos[self.cam] = self._cam_pos + ep.cam_shift
        quat = np.zeros(4)
        mujoco.mju_mulQuat(quat, ep.cam_rot, self._cam_quat)
        m.cam_quat[self.cam] = quat

    def restore(self) -> None:
        m = self.model
        m.light_diffuse[:] = self._light_diffuse
        m.light_dir[:] = self._light_dir
        m.cam_pos[self.cam] = self._cam_pos
        m.cam_quat[self.cam] = self._cam_quat


@dataclass(frozen=True)
class FrameDraw:
    """One frame's random draws: where its sensor noise is cut from the episode's field."""

    noise_offset: tuple[int, int]


def draw_frame(ep: EpisodeImaging, cfg: NoiseConfig, rng: np.random.Generator
               ) -> FrameDraw | None:
    """The frame's draws, in the stream's order; None when the frame is dropped."""
    if cfg.drop_prob and rng.random() < cfg.drop_prob:
        return None
    if ep.sensor_field is None:
        return FrameDraw((0, 0))
    dy, dx = rng.integers(0, FIELD_MARGIN, size=2)
    return FrameDraw((int(dy), int(dx)))


def apply_chain(img: np.ndarray, ep: EpisodeImaging, draw: FrameDraw,
                origin: tuple[int, int] = (0, 0)) -> np.ndarray:
    """Blur, lens, sensor noise and JPEG on a frame, or on a crop of it whose top-left pixel
    is `origin` (y, x) in the frame: see `regions` for crops that match the whole frame."""
    if ep.blur_kernel is not None:
        img = cv2.filter2D(img, -1, ep.blur_kernel)
    if ep.psf is not None:     # two passes: 0.5 ms where one 7 x 7 kernel takes 2 ms here
        img = cv2.sepFilter2D(img, -1, ep.psf, ep.psf)
    if ep.sensor_field is not None:
        dy, dx = draw.noise_offset
        img = ep.sensor_field.add_to(img, dy + origin[0], dx + origin[1])
    if ep.jpeg_quality < 100:
        img = jpeg_round_trip(img, ep.jpeg_quality)
    return img


def degrade(rgb: np.ndarray, ep: EpisodeImaging, cfg: NoiseConfig,
            rng: np.random.Generator) -> np.ndarray | None:
    """One frame through the camera chain; None when the frame is dropped."""
    draw = draw_frame(ep, cfg, rng)
    return None if draw is None else apply_chain(rgb, ep, draw)


MCU = 16        # JPEG's 4:2:0 minimum coded unit (px): blocks are coded independently
CROP_MARGIN = 32      # two MCUs: the decoder's chroma upsampling reads a block row beyond


def regions(rgb: np.ndarray, ep: EpisodeImaging, draw: FrameDraw,
            rects: list[tuple[int, int, int, int]]) -> list[tuple[int, int, np.ndarray]]:
    """The camera chain on parts of a frame only: for each rect (x0, y0, x1, y1), its pixels
    as `apply_chain` on the whole frame makes them, as (x0, y0, image).

    Why they match: each rect is processed inside a crop two JPEG blocks (MCUs) wider on every
    side and aligned to the frame's MCU grid, so JPEG codes the same blocks from the same
    pixels; the filters' footprints (a few px) and the noise field's offsets stay inside it."""
    h, w = rgb.shape[:2]
    out = []
    for x0, y0, x1, y1 in rects:
        cx0 = max(0, (x0 - CROP_MARGIN) // MCU * MCU)
        cy0 = max(0, (y0 - CROP_MARGIN) // MCU * MCU)
        cx1 = min(w, -(-(x1 + CROP_MARGIN) // MCU) * MCU)
        cy1 = min(h, -(-(y1 + CROP_MARGIN) // MCU) * MCU)
        crop = apply_chain(np.ascontiguousarray(rgb[cy0:cy1, cx0:cx1]), ep, draw, (cy0, cx0))
        out.append((x0, y0, crop[y0 - cy0:y1 - cy0, x0 - cx0:x1 - cx0]))
    return out


def jpeg_round_trip(rgb: np.ndarray, quality: int) -> np.ndarray:
    """Compress and decompress as the testbed's camera stream did."""
    # cvtColor, not [..., ::-1] views: strided arrays make OpenCV copy slowly (5x here).
    bgr = cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR)
    _, buf = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, quality])
    return cv2.cvtColor(cv2.imdecode(buf, cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
