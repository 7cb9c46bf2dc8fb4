"""The tracker for a world's marker kind: colour triangles or fiducial tags.

One home for the pairing, keyed by the scenario's marker object's type (the marker classes live
in `chain`, below the trackers, so they cannot name their tracker themselves).
"""

from __future__ import annotations

import mujoco

from macrostate_mj.chain.markers import ColourMarkers
from macrostate_mj.chain.rendered import check_rendered_colours
from macrostate_mj.chain.tags import ArucoMarkers
from macrostate_mj.chain.world import World
from macrostate_mj.vision.aruco import ArucoTracker
from macrostate_mj.vision.tracker import Tracker

TRACKERS: dict[type, type[Tracker] | type[ArucoTracker]] = {
    ColourMarkers: Tracker, ArucoMarkers: ArucoTracker}


def tracker_for(world: World, data: mujoco.MjData,
                distortion: tuple[float, float, float, float] | None = None
                ) -> Tracker | ArucoTracker:
    """The tracker of a compiled chain world, by its scenario's markers (`for_world` of it);
    a robot part that would pass for a marker as the camera films it is refused first (a
    `UserError`; cached, so an episode's tracker costs microseconds after the first)."""
    check_rendered_colours(world.scenario, len(world.names))
    return TRACKERS[type(world.scenario.markers)].for_world(world, data, distortion)
