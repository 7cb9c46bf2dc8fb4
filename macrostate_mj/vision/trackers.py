"""The tracker for a world's marker kind: colour triangles or fiducial tags.

One home for the pairing, keyed by the scenario's marker object's type (the marker classes live
in `chain`, below the trackers, so they cannot name their tracker themselves).
"""

from __future__ import annotations

import mujoco

from macrostate_mj.chain.markers import ColourMarkers
from macrostate_mj.chain.tags import ArucoMarkers
from macrostate_mj.chain.world import World
from macrostate_mj.vision.aruco import ArucoTracker
from macrostate_mj.vision.tracker import Tracker

TRACKERS: dict[type, type[Tracker] | type[ArucoTracker]] = {
    ColourMarkers: Tracker, ArucoMarkers: ArucoTracker}


def tracker_for(world: World, data: mujoco.MjData,
                distortion: tuple[float, float, float, float] | None = None
                ) -> Tracker | ArucoTracker:
    """The tracker of a compiled chain world, by its scenario's markers (`for_world` of it)."""
    return TRACKERS[type(world.scenario.markers)].for_world(world, data, distortion)
