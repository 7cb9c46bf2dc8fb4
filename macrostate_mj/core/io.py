"""Atomic outputs and output-path checks: one home for how runs write files (the run lifecycle
and its manifest are `core.run`'s).

Every output goes to a temporary sibling first and is renamed into place, so an interrupted run
never leaves a half-written file under its final name.
"""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
from collections.abc import Iterator
from dataclasses import asdict, is_dataclass
from pathlib import Path
from typing import Any

from macrostate_mj.core.errors import UserError


class AtomicFile:
    """A temporary path beside `final` (same extension, for writers that pick a format from it)
    that becomes `final` on `commit()` and disappears on `discard()`."""

    def __init__(self, final: str | os.PathLike):
        self.final = Path(final)
        self.final.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{self.final.stem}.",
                                   suffix=f".part{self.final.suffix}", dir=self.final.parent)
        os.close(fd)
        self.tmp = Path(tmp)

    def commit(self) -> None:
        # mkstemp creates 0600; give the final file the usual umask-derived mode.
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(self.tmp, 0o666 & ~umask)
        os.replace(self.tmp, self.final)

    def discard(self) -> None:
        self.tmp.unlink(missing_ok=True)


@contextlib.contextmanager
def atomic_path(final: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path beside `final`; rename it onto `final` only if the block succeeds."""
    f = AtomicFile(final)
    try:
        yield f.tmp
        f.commit()
    finally:
        f.discard()


def write_text_atomic(final: str | os.PathLike, text: str) -> None:
    with atomic_path(final) as tmp:
        tmp.write_text(text)


def write_json_atomic(final: str | os.PathLike, obj: Any) -> None:
    write_text_atomic(final, json.dumps(jsonable(obj), indent=2, sort_keys=True) + "\n")


def check_writable_file(path: str | os.PathLike, overwrite: bool, what: str = "output") -> Path:
    """Fail early (before any work) if `path` exists without --overwrite or cannot be written."""
    path = Path(path)
    if path.exists() and not overwrite:
        raise UserError(f"{what} {path} already exists; pass --overwrite or choose another path")
    check_writable_dir(path.parent, create=False)
    return path


def check_writable_dir(path: str | os.PathLike, create: bool = True) -> Path:
    """Make sure `path` is (or can become) a writable folder; create it only if asked."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise UserError(f"{path} is a file, not a folder; choose a folder path for the output")
    probe = path
    while not probe.exists():
        probe = probe.parent
    if not probe.is_dir():
        raise UserError(f"cannot create {path}: {probe} is a file; choose a folder path")
    if not os.access(probe, os.W_OK | os.X_OK):
        raise UserError(f"cannot write to {path} (permission denied); choose a writable folder")
    if create:
        path.mkdir(parents=True, exist_ok=True)
    return path


def jsonable(obj: Any) -> Any:
    if is_dataclass(obj) and not isinstance(obj, type):
        return jsonable(asdict(obj))
    if isinstance(obj, dict):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [jsonable(v) for v in obj]
    if isinstance(obj, Path):
        return str(obj)
    if hasattr(obj, "tolist"):
        return obj.tolist()
    return obj


class Mp4Writer:
    """The one MP4 writer: H.264 (yuv420p, plays in browsers), RGB frames to a temporary sibling
    renamed into place by `commit()` (an interrupted run leaves no broken video); `discard()`
    removes it. Usable as a context manager that commits on success. Encoding is single-threaded
    with fixed settings, so the same frames give the same bytes.

    Frames are stamped evenly at `fps`, unless a subclass sets TIME_BASE (s, a `Fraction`): then
    `write(rgb, t)` stamps each frame with its own time `t` (variable frame rate), and x264 is
    told to keep its rate control on the nominal `fps` (`force-cfr`), so the stamps never change
    a pixel."""

    CODEC = "libx264"
    CRF = 20            # visually lossless for these flat scenes, ~1/10 the size of mp4v
    PIX_FMT = "yuv420p"     # subclasses for data, not browsers, keep full chroma (yuv444p)
    TIME_BASE: Any = None   # subclasses whose frames carry their own times set a Fraction

    def __init__(self, path: str | os.PathLike, fps: float, size: tuple[int, int]):
        from fractions import Fraction

        import av

        self.path = Path(path)
        self.size = (int(size[0]), int(size[1]))
        self._file = AtomicFile(self.path)
        try:
            self._container = av.open(str(self._file.tmp), mode="w", format="mp4")
            stream = self._container.add_stream(self.CODEC,
                                                rate=Fraction(fps).limit_denominator(1000))
        except (av.FFmpegError, ValueError) as err:
            self._file.discard()
            raise UserError(f"cannot write MP4 video {self.path} ({err}); choose another "
                            "path") from None
        # H.264 needs even sides; odd frames are padded by one edge pixel
        stream.width, stream.height = (self.size[0] + 1) // 2 * 2, (self.size[1] + 1) // 2 * 2
        stream.pix_fmt = self.PIX_FMT
        stream.thread_count = 1
        stream.options = {"crf": str(self.CRF), "preset": "veryfast"}
        if self.TIME_BASE is not None:
            stream.codec_context.time_base = self.TIME_BASE
            stream.options = {**stream.options, "x264-params": "force-cfr=1"}
        self._stream = stream
        self.frames = 0
        self._last_pts: int | None = None

    def write(self, rgb: Any, t: float | None = None) -> None:
        """Append an RGB frame; `t`: the time it is shown at (s, later than the frame before's),
        for a writer with a TIME_BASE, which needs it."""
        import av
        import numpy as np

        if (t is None) != (self.TIME_BASE is None):
            raise ValueError(f"{type(self).__name__}.write takes a frame time t exactly when "
                             "the writer has a TIME_BASE")
        rgb = np.asarray(rgb, np.uint8)
        pad_h, pad_w = self._stream.height - rgb.shape[0], self._stream.width - rgb.shape[1]
        if pad_h or pad_w:
            rgb = np.pad(rgb, ((0, pad_h), (0, pad_w), (0, 0)), mode="edge")
        frame = av.VideoFrame.from_ndarray(np.ascontiguousarray(rgb), format="rgb24")
        if t is not None:
            pts = round(float(t) / self.TIME_BASE)
            if self._last_pts is not None and pts <= self._last_pts:
                before = float(self._last_pts * self.TIME_BASE)
                raise ValueError(f"frame times must increase by a tick of {self.TIME_BASE} s at "
                                 f"least; got {t!r} after {before!r}")
            frame.pts, frame.time_base, self._last_pts = pts, self.TIME_BASE, pts
        for packet in self._stream.encode(frame):
            self._container.mux(packet)
        self.frames += 1

    def write_bgr(self, bgr: Any) -> None:
        self.write(bgr[:, :, ::-1])

    def _close(self) -> None:
        if self._container is not None:
            for packet in self._stream.encode(None):
                self._container.mux(packet)
            self._container.close()
            self._container = None

    def commit(self) -> Path:
        self._close()
        self._file.commit()
        return self.path

    def discard(self) -> None:
        try:
            self._close()
        finally:
            self._file.discard()

    def __enter__(self) -> Mp4Writer:
        return self

    def __exit__(self, exc_type: object, *exc: object) -> None:
        if exc_type is None:
            self.commit()
        else:
            self.discard()
