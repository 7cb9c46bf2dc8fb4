"""Flow-pipeline speed: our per-pair path (DIS + TSN encoding) vs bare DIS on the same pairs."""

from __future__ import annotations

import time

import numpy as np

from macrostate_mj.app.bench import SUITES, figure


def _pairs(n: int, size: int, seed: int = 0) -> list[tuple[np.ndarray, np.ndarray]]:
    """Textured grey frames, each next one shifted by a random sub-frame motion."""
    import cv2

    rng = np.random.default_rng(seed)
    base = cv2.GaussianBlur((rng.random((size * 2, size * 2)) * 255).astype(np.uint8), (0, 0), 1.5)
    out = []
    for _ in range(n):
        x, y = rng.integers(0, size, 2)
        dx, dy = rng.normal(0, 2, 2)
        a = np.ascontiguousarray(base[y:y + size, x:x + size])
        warp = np.float32([[1, 0, dx], [0, 1, dy]])
        out.append((a, cv2.warpAffine(a, warp, (size, size), borderMode=cv2.BORDER_REFLECT)))
    return out


def _rates(fns, pairs, repeats: int) -> list[float]:
    """Best pairs/s of each function; rounds interleaved so a busy CPU hurts both alike."""
    for fn in fns:
        fn(*pairs[0])  # warm-up (allocations)
    best = [0.0] * len(fns)
    for _ in range(repeats):
        for i, fn in enumerate(fns):
            t = time.perf_counter()
            for a, b in pairs:
                fn(a, b)
            best[i] = max(best[i], len(pairs) / (time.perf_counter() - t))
    return best


@SUITES.register("flow", rank=90)
def bench_flow(n: int = 400, size: int = 64, repeats: int = 5) -> list[dict]:
    """Pairs/s on one core at size × size: our FlowComputer + encode_flow vs bare DIS.calc."""
    import cv2

    from macrostate_mj.vision.flow import FlowComputer, dis_preset, encode_flow

    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        pairs = _pairs(n, size)
        bare = cv2.DISOpticalFlow_create(dis_preset((size, size)))
        ours_fc = FlowComputer("dis")
        limit, ours = _rates([lambda a, b: bare.calc(a, b, None),
                              lambda a, b: encode_flow(ours_fc(a, b))], pairs, repeats)
    finally:
        cv2.setNumThreads(threads)
    return [figure("flow_dis_encode_pairs_per_s", ours, "pairs/s", limit,
                   config=f"{size}x{size}, 1 core, against bare DIS.calc")]
