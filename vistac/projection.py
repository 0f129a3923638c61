"""World to pixel: the one projection of every image the simulator makes.

`Projection` is the camera an image was made with: the plain orthographic top view, the same
view tilted and rolled (`camera_jitter`), or the perspective phone camera of the ``photo``
preset (tilted and rolled). The renderer (`vistac_sim.render.shot.Shot.projection`) sets
MuJoCo's camera from it and projects the finger outlines with it; the learner rebuilds it from a
configuration's columns (`Projection.from_columns`) to place the simulator's fingertips and
contact points in the image. `displace` is the drawn overlay's displacement (a finger drawn off
the real one: turned about the fingertip, then shifted), used by both too.

Coordinates: world metres, z up, the table top at z = 0; continuous pixel coordinates (u right,
v down) in which pixel (u, v) covers [u, u + 1) x [v, v + 1) (subtract
`vistac.dataset.schema.PIXEL_CENTRE` for OpenCV's and the locator's convention).

Numpy only: the learner imports it without the simulator.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

CAMERA_DISTANCE = 1.0  # m, the scene camera's height above the table (sim_assets/hand/scene.xml)

Overlay = tuple[float, float, float]
"""A drawn finger's displacement against the real one: (dx, dy) m and a turn (rad) about the
fingertip, turned first."""
NO_OVERLAY: Overlay = (0.0, 0.0, 0.0)

# The camera's columns of a configuration row (``configs.parquet``): where it looks and the
# scale there, then its angles in degrees (absent or NaN: 0); the last two only for a
# perspective camera.
CENTRE_COLUMNS = ("camera_x", "camera_y", "px_per_m")
ANGLE_COLUMNS = ("camera_tilt_deg", "camera_tilt_azimuth_deg", "camera_roll_deg")
PERSPECTIVE_COLUMNS = ("camera_fovy_deg", "camera_height")
CAMERA_COLUMNS = (*CENTRE_COLUMNS, *ANGLE_COLUMNS, PERSPECTIVE_COLUMNS[0])
"""The columns `Projection.from_columns` reads."""


@dataclass(frozen=True)
class Projection:
    """The camera of one image.

    Attributes:
        image_size: Image side, pixels (square images).
        px_per_m: Pixels per metre at the table point under the image centre.
        center: World (x, y) where the view axis meets the table (the image centre), m.
        tilt: Angle of the view axis off vertical, rad.
        tilt_azimuth: Direction (from world +x towards +y) the view axis leans to, rad.
        roll: Rotation of the camera about its view axis, rad (counter-clockwise seen from above).
        fovy: Vertical field of view of a perspective camera, rad; 0 is the orthographic view.
            A perspective camera stands as high above `center` as gives `px_per_m` there.
    """

    image_size: int
    px_per_m: float
    center: tuple[float, float] = (0.0, 0.0)
    tilt: float = 0.0
    tilt_azimuth: float = 0.0
    roll: float = 0.0
    fovy: float = 0.0

    @property
    def perspective(self) -> bool:
        """True for a perspective camera (`fovy` > 0)."""
        return self.fovy > 0

    @property
    def focal_px(self) -> float:
        """Focal length in pixels of a perspective camera."""
        return self.image_size / 2 / np.tan(self.fovy / 2)

    @property
    def distance(self) -> float:
        """The camera's distance from the table point at the image centre, m."""
        if not self.perspective:
            return CAMERA_DISTANCE
        return self.focal_px / self.px_per_m

    def frame(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(pos, right, up, forward) of the camera in world coordinates (read-only arrays).

        The plain camera looks straight down from above `center` with image right = world +x and
        image up = world +y. Roll turns (right, up) about the vertical, then the tilt turns the
        whole frame about the horizontal axis that leans the view axis towards `tilt_azimuth`.
        """
        return self._frame

    @functools.cached_property
    def _frame(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        cr, sr = np.cos(self.roll), np.sin(self.roll)
        right, up, fwd = np.array([cr, sr, 0.0]), np.array([-sr, cr, 0.0]), np.array([0, 0, -1.0])
        tilt = rotation(np.array([-np.sin(self.tilt_azimuth), np.cos(self.tilt_azimuth), 0.0]),
                        self.tilt)
        right, up, fwd = tilt @ right, tilt @ up, tilt @ fwd
        pos = np.array([self.center[0], self.center[1], 0.0]) - self.distance * fwd
        for v in (pos, right, up, fwd):
            v.setflags(write=False)
        return pos, right, up, fwd

    def project(self, points: np.ndarray) -> np.ndarray:
        """Continuous pixel coordinates (u right, v down) of world points (..., 3)."""
        pos, right, up, fwd = self.frame()
        d = np.asarray(points, float) - pos
        half = self.image_size / 2
        if self.perspective:
            s = self.focal_px / (d @ fwd)
        else:
            s = self.px_per_m
        return np.stack([half + d @ right * s, half - d @ up * s], axis=-1)

    def direction(self, points: np.ndarray, vectors: np.ndarray) -> np.ndarray:
        """Image directions (u, v) (..., 2) of world `vectors` (..., 3) leaving `points` (..., 3):
        the derivative of `project` along each vector, up to a positive factor (normalise it).

        The orthographic view gives (v . right, -v . up); a perspective one adds the change of
        depth along the vector.
        """
        pos, right, up, fwd = self.frame()
        vec = np.asarray(vectors, float)
        vr, vu = vec @ right, vec @ up
        if not self.perspective:
            return np.stack([vr, -vu], axis=-1)
        d = np.asarray(points, float) - pos
        depth, vf = d @ fwd, vec @ fwd
        return np.stack([vr * depth - (d @ right) * vf, -(vu * depth - (d @ up) * vf)], axis=-1)

    def px_per_m_at(self, points: np.ndarray) -> np.ndarray:
        """Pixels per metre of the image at world points (..., 3) (for a small length across
        the view axis)."""
        points = np.asarray(points, float)
        if not self.perspective:
            return np.full(points.shape[:-1], self.px_per_m)
        pos, _, _, fwd = self.frame()
        return self.focal_px / ((points - pos) @ fwd)

    # ------------------------------------------------------------- configuration columns
    def columns(self) -> dict[str, float]:
        """The camera's columns of a configuration row (`CENTRE_COLUMNS`, `ANGLE_COLUMNS`);
        a perspective camera's own columns are `perspective_columns`."""
        values = (*self.center, self.px_per_m, *np.degrees([self.tilt, self.tilt_azimuth,
                                                             self.roll]))
        return {k: float(v) for k, v in zip((*CENTRE_COLUMNS, *ANGLE_COLUMNS), values,
                                            strict=True)}

    def perspective_columns(self) -> dict[str, float]:
        """The perspective camera's `PERSPECTIVE_COLUMNS` (none for the orthographic view)."""
        if not self.perspective:
            return {}
        return dict(zip(PERSPECTIVE_COLUMNS, (float(np.degrees(self.fovy)),
                                              float(self.distance)), strict=True))

    @classmethod
    def from_columns(cls, row: Mapping, image_size: int) -> Projection:
        """The camera of a configuration row: `CENTRE_COLUMNS` are required (KeyError), the
        angle columns of `CAMERA_COLUMNS` are 0 where absent or NaN."""
        x, y, ppm = (float(row[k]) for k in CENTRE_COLUMNS)
        tilt, azimuth, roll, fovy = (_angle(row, k) for k in CAMERA_COLUMNS[3:])
        return cls(int(image_size), ppm, (x, y), tilt, azimuth, roll, fovy)


def _angle(row: Mapping, column: str) -> float:
    """An angle column in radians (absent or NaN: 0)."""
    v = row.get(column)
    if v is None or not math.isfinite(float(v)):
        return 0.0
    return float(np.radians(float(v)))


# ------------------------------------------------------------------ the drawn overlay
def displace(points: np.ndarray, pivot: np.ndarray, overlay: Overlay) -> np.ndarray:
    """World points (..., 3) of a finger drawn off the real one: turned by the overlay's angle
    about `pivot` (the fingertip), then shifted by its (dx, dy)."""
    dx, dy, da = overlay
    pivot = np.asarray(pivot, float)
    return pivot + (np.asarray(points, float) - pivot) @ rotz(da).T + np.array([dx, dy, 0.0])


def overlay_columns(finger: str, overlay: Overlay) -> dict[str, float]:
    """A finger's overlay columns of a configuration row (angle in degrees)."""
    dx, dy, da = overlay
    return {f"overlay_{finger}_dx": float(dx), f"overlay_{finger}_dy": float(dy),
            f"overlay_{finger}_rot_deg": float(np.degrees(da))}


def overlay_from_columns(row: Mapping, finger: str) -> Overlay:
    """A finger's overlay of a configuration row (absent or NaN columns: none)."""
    vals = []
    for key in (f"overlay_{finger}_dx", f"overlay_{finger}_dy", f"overlay_{finger}_rot_deg"):
        v = row.get(key)
        vals.append(float(v) if v is not None and math.isfinite(float(v)) else 0.0)
    return vals[0], vals[1], float(np.radians(vals[2]))


# --------------------------------------------------------------------------- rotations
def rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rotation matrix of `angle` rad about unit `axis` (Rodrigues)."""
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * (k @ k)


def rotz(angle: float) -> np.ndarray:
    """Rotation matrix of `angle` rad about the world z axis."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


__all__ = ["ANGLE_COLUMNS", "CAMERA_COLUMNS", "CAMERA_DISTANCE", "CENTRE_COLUMNS", "NO_OVERLAY",
           "Overlay", "PERSPECTIVE_COLUMNS", "Projection", "displace", "overlay_columns",
           "overlay_from_columns", "rotation", "rotz"]
