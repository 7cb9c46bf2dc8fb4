"""Fiducial tags as robot markers: each robot's marker plate shows an ArUco tag whose id is the
robot's index (`[markers] kind = "aruco"` in a scenario file).

Why tags beside colours: hues crowd as teams grow (`chain.markers`), an id code does not. The
plate is a square the length of the robot's marker card, centred over the body origin at the
card's height, the tag's top edge forward (+x), so the tracker (`vision.aruco`) reads position
from its corners and heading from their order. The texture is the tag image magnified with
nearest neighbours (TEXELS_PER_CELL), so MuJoCo's filtering blurs it no more than a lens would.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import cv2
import mujoco
import numpy as np

from macrostate_mj.core.errors import UserError

TEXELS_PER_CELL = 8     # texture pixels per tag cell: sharp edges after MuJoCo's mipmaps
QUIET_CELLS = 1         # the white border around the tag's black frame, in cells
PLATE_RGBA = (1.0, 1.0, 1.0, 1.0)    # white x the texture: the tag's own black and white


def dictionaries() -> list[str]:
    """The names of OpenCV's predefined ArUco dictionaries (`cv2.aruco.DICT_*`)."""
    return sorted(n for n in dir(cv2.aruco) if n.startswith("DICT_"))


@cache
def dictionary(name: str) -> cv2.aruco.Dictionary:
    return cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, name))


@dataclass(frozen=True)
class ArucoMarkers:
    """Each robot wears an ArUco tag of `dictionary` (OpenCV's name), id = its index."""

    dictionary: str = "DICT_4X4_50"

    def __post_init__(self) -> None:
        if self.dictionary not in dictionaries():
            raise UserError(f"markers.dictionary {self.dictionary!r} is not an OpenCV ArUco "
                            f"dictionary; use one of {', '.join(dictionaries())}", "dictionary")

    @property
    def ids(self) -> int:
        """How many distinct tags the dictionary holds."""
        return int(dictionary(self.dictionary).bytesList.shape[0])

    @property
    def cells(self) -> int:
        """Cells across a tag as drawn: its bits, the black frame and the quiet border."""
        return dictionary(self.dictionary).markerSize + 2 + 2 * QUIET_CELLS

    @property
    def pattern(self) -> float:
        """The share of the plate's side the detector needs in view: the black frame and its
        bits (the quiet border may be hidden)."""
        return (self.cells - 2 * QUIET_CELLS) / self.cells

    def check_team(self, n: int) -> None:
        """Every robot needs an id of its own."""
        if n > self.ids:
            raise UserError(f"{n} robots need {n} tag ids but {self.dictionary} has {self.ids}; "
                            "use a larger dictionary (e.g. DICT_4X4_100 or DICT_4X4_250)", "robots")

    def colour_teams(self, capacity: int) -> int | None:
        """Tags are black and white: a robot's colours cannot pass for one."""
        return None

    def colours(self, n: int) -> np.ndarray:
        """The plates' colour (white: the texture draws the tag)."""
        return np.tile(PLATE_RGBA[:3], (n, 1))

    def image(self, tag: int) -> np.ndarray:
        """Tag `tag` as an RGB texture (uint8), quiet border included, top row forward."""
        d = dictionary(self.dictionary)
        side = (d.markerSize + 2) * TEXELS_PER_CELL
        img = cv2.aruco.generateImageMarker(d, tag, side)
        pad = QUIET_CELLS * TEXELS_PER_CELL
        img = cv2.copyMakeBorder(img, pad, pad, pad, pad, cv2.BORDER_CONSTANT, value=255)
        return np.ascontiguousarray(np.repeat(img[..., None], 3, axis=2))

    def dress(self, spec: mujoco.MjSpec, names: list[str], colours: np.ndarray) -> None:
        """Turn each robot's marker card into a square plate showing tag i."""
        for i, name in enumerate(names):
            img = self.image(i)
            tex = spec.add_texture(name=f"{name}/tag", type=mujoco.mjtTexture.mjTEXTURE_2D,
                                   width=img.shape[1], height=img.shape[0], nchannel=3)
            tex.data = img.tobytes()
            mat = spec.add_material(name=f"{name}/tag", rgba=[1, 1, 1, 1], specular=0.0,
                                    shininess=0.0, reflectance=0.0)
            mat.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = f"{name}/tag"
            geom = spec.geom(f"{name}/marker")
            _plate(spec.mesh(f"{name}/marker"), geom)
            geom.material = f"{name}/tag"
            geom.rgba = [*colours[i], PLATE_RGBA[3]]


def _plate(mesh: mujoco.MjsMesh, geom: mujoco.MjsGeom) -> None:
    """Make the card's mesh a square prism as long as the card and as thick, centred over the
    body origin with sides along the body's axes; texture coordinates put the tag's top row at
    +x and its left column at +y (as the tag reads from above, forward up)."""
    verts = np.asarray(mesh.uservert, float).reshape(-1, 3)
    half = (verts[:, 0].max() - verts[:, 0].min()) / 2
    z0, z1 = verts[:, 2].min(), verts[:, 2].max()
    rot = np.zeros(9)
    mujoco.mju_quat2Mat(rot, np.asarray(geom.quat, float))
    rot = rot.reshape(3, 3)                     # geom frame -> body frame
    corners = np.array([[half, half], [half, -half], [-half, -half], [-half, half]])
    body = [[x, y, z] for z in (z1, z0) for x, y in corners]
    pos = np.asarray(geom.pos, float)
    # Body-frame xy, z in the card's own frame (the card is flat: its z axis is the body's).
    local = [(rot.T @ (np.array([x, y, 0.0]) - [pos[0], pos[1], 0.0]))[:2].tolist() + [z]
             for x, y, z in body]
    mesh.uservert = np.ravel(local).tolist()
    uv = [[0, 0], [1, 0], [1, 1], [0, 1]]
    mesh.usertexcoord = np.ravel(uv + uv).tolist()
    top, bottom = [0, 2, 1, 0, 3, 2], [4, 5, 6, 4, 6, 7]
    sides = []
    for a in range(4):
        b = (a + 1) % 4
        sides += [a, b, b + 4, a, b + 4, a + 4]
    mesh.userface = top + bottom + sides
