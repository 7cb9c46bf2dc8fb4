"""The sim-to-real gap, ranked: which motion statistic a lab collection gets most wrong against
a real file, and which of the lab's parameters shape it (what `sysid` can move, what the
randomization profiles draw, `collectors.randomize`).

The ranking is `motion_stats.rank` (each statistic's KS distance per robot, an
autocorrelation's lags as one); the parameters beside each are the lab's models of it, so a
statistic high in the ranking with nothing beside it is a difference the lab does not model.
"""

from __future__ import annotations

from collectors.randomize import PARAMETERS
from macrostate_mj.formats import motion_stats

# Which of the lab's parameters move each statistic (by the chain's rules: the Head's speed cap
# and the Followers' gains, cap and wait rule drive speeds and spacing; the heading gain turns;
# the tracker's noise makes the frame-to-frame jitter and, through it, accelerations and the
# autocorrelations' short lags, as frames of uneven age do (the camera's frame rate and timing
# jitter, and rows that alternate between two frame ages); wheel grip and motor torque limit
# accelerations; the rear robots' start gap sets when they stop and go).
SHAPED_BY: dict[str, tuple[str, ...]] = {
    "spacing_cm": ("k_f", "k_t", "wait_slack", "follow_start"),
    "speed_cm_s": ("head_speed", "chain_speed", "k_f", "k_t", "wait_slack", "follow_start",
                   "frame_hz", "frame_jitter", "frame_alternation", "wheel_spread",
                   "head_turn_speed"),
    "turn_deg_s": ("k_omega", "marker_jitter", "head_jitter_scale", "wheel_spread",
                   "marker_offset"),
    "heading_change_deg": ("k_omega", "marker_jitter", "head_jitter_scale", "wheel_spread",
                           "marker_offset"),
    "accel_cm_s2": ("motor_torque", "wheel_friction", "marker_jitter", "head_jitter_scale",
                    "frame_hz", "frame_jitter", "frame_alternation"),
    "jitter_cm": ("marker_jitter", "head_jitter_scale", "sensor_sigma", "blur_px",
                  "psf_sigma_px", "frame_jitter", "frame_alternation"),
    "wait_share": ("wait_slack", "follow_start", "chain_speed", "k_f"),
    "speed_acf": ("frame_hz", "frame_jitter", "frame_alternation", "marker_jitter",
                  "head_jitter_scale", "k_f", "k_t", "head_turn_speed"),
    "turn_acf": ("k_omega", "marker_jitter", "head_jitter_scale", "frame_hz", "frame_jitter"),
}
assert all(set(v) <= set(PARAMETERS) for v in SHAPED_BY.values())


def ranked_gap(rows: list[dict], effects: dict[str, dict] | None = None) -> list[dict]:
    """`motion_stats.rank` of compared rows, each with the lab parameters that shape it and,
    given `effects` (`experiment sim2real --ablate`'s `ablations`: a comma-joined group of
    parameters -> its sim-only Head error minus the lab's), what switching off each group
    that shapes the statistic does to the estimator."""
    out = []
    for r in motion_stats.rank(rows):
        shaped = SHAPED_BY.get(r["statistic"], ())
        row = {**r, "shaped_by": list(shaped)}
        if effects is not None:
            row["effects"] = {group: cell["minus_lab"] for group, cell in effects.items()
                              if set(group.split(",")) & set(shaped)}
        out.append(row)
    return out
