"""The render request of one configuration: the sampled parameters of every image effect.

An image effect (`vistac_sim.effects`, stage ``image``) is ``effect(view, rng) -> view`` on a
`View`. A `View` holds only sampled parameters (kornia-style: a sample can be replayed exactly
from them); `vistac_sim.render.view_render` turns it into pixels and into the finger boxes the
image really shows. With image effects, the configuration row gets the view's parameters
(`View.columns`), whose ``camera_x, camera_y, px_per_m`` describe the projection the image was
made with.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from vistac.dataset import FINGERS
from vistac_sim.render.config import RenderCfg

CAMERA_DISTANCE = 1.0  # m, the scene camera's height above the table (sim_assets/hand/scene.xml)
HEADLIGHT = (0.45, 0.55)  # ambient, diffuse of the scene's headlight (sim_assets/hand/scene.xml)


# ------------------------------------------------------------------------------- the request
@dataclass(frozen=True)
class CameraPose:
    """Where the orthographic top camera looks from, relative to the clean view.

    Attributes:
        center: World (x, y) where the view axis meets the table (the image centre), m.
        scale: Pixels per metre relative to the clean view (> 1: zoomed in).
        tilt: Angle of the view axis off vertical, rad.
        tilt_azimuth: Direction (from world +x towards +y) the view axis leans to, rad.
        roll: Rotation of the camera about its view axis, rad (counter-clockwise seen from above).
    """

    center: tuple[float, float] = (0.0, 0.0)
    scale: float = 1.0
    tilt: float = 0.0
    tilt_azimuth: float = 0.0
    roll: float = 0.0


@dataclass(frozen=True)
class Light:
    """A directional key light (angles in rad; colours are grey levels in [0, 1])."""

    elevation: float
    azimuth: float
    diffuse: float
    ambient: float
    specular: float = 0.0

    @property
    def direction(self) -> np.ndarray:
        """Unit vector the light travels along (pointing down onto the table)."""
        ce = np.cos(self.elevation)
        return -np.array([ce * np.cos(self.azimuth), ce * np.sin(self.azimuth),
                          np.sin(self.elevation)])


@dataclass(frozen=True)
class TableTexture:
    """A multiplicative brightness pattern on the table, replayable from its seed."""

    seed: int
    strength: float  # relative std of the brightness
    scale: float  # m, grain size of the coarsest layer
    octaves: int = 3


@dataclass(frozen=True)
class View:
    """The render request of one configuration: the sampled parameters of every image effect.

    Attributes:
        image_size: Image side, pixels.
        view_extent: Metres of table across the clean image.
        table_rgb: Table colour in [0, 1].
        overlay: Per finger (index, thumb): (dx, dy, dyaw) of the drawn finger against the real
            one, m and rad, turned about the fingertip then shifted.
        camera: The camera pose.
        light: The key light, or None for the scene's headlight.
        shadows: Whether the key light casts shadows.
        texture: The table's brightness pattern, or None.
    """

    image_size: int
    view_extent: float
    table_rgb: tuple[float, float, float]
    overlay: tuple[tuple[float, float, float], ...] = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    camera: CameraPose = field(default_factory=CameraPose)
    light: Light | None = None
    shadows: bool = False
    texture: TableTexture | None = None

    @classmethod
    def of(cls, cfg: RenderCfg) -> View:
        """The clean view of a render config."""
        return cls(cfg.image_size, cfg.view_extent, tuple(cfg.table_rgb))

    @property
    def px_per_m(self) -> float:
        """Pixels per metre of this view."""
        return self.image_size / self.view_extent * self.camera.scale

    def frame(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(pos, right, up, forward) of the camera in world coordinates.

        The clean camera looks straight down from (0, 0, 1) with image right = world +x and image
        up = world +y. Roll turns (right, up) about the vertical, then the tilt turns the whole
        frame about the horizontal axis that leans the view axis towards `tilt_azimuth`.
        """
        c = self.camera
        cr, sr = np.cos(c.roll), np.sin(c.roll)
        right, up, fwd = np.array([cr, sr, 0.0]), np.array([-sr, cr, 0.0]), np.array([0, 0, -1.0])
        tilt = _rotation(np.array([-np.sin(c.tilt_azimuth), np.cos(c.tilt_azimuth), 0.0]), c.tilt)
        right, up, fwd = tilt @ right, tilt @ up, tilt @ fwd
        pos = np.array([c.center[0], c.center[1], 0.0]) - CAMERA_DISTANCE * fwd
        return pos, right, up, fwd

    def project(self, points: np.ndarray) -> np.ndarray:
        """Continuous pixel coordinates (u right, v down) of world points (..., 3)."""
        pos, right, up, _ = self.frame()
        d = np.asarray(points, float) - pos
        s, half = self.px_per_m, self.image_size / 2
        return np.stack([half + d @ right * s, half - d @ up * s], axis=-1)

    def columns(self) -> dict:
        """The view's parameters as configuration-table columns (angles in degrees)."""
        c, nan = self.camera, float("nan")
        row = {"camera_x": float(c.center[0]), "camera_y": float(c.center[1]),
               "px_per_m": float(self.px_per_m), "camera_tilt_deg": float(np.degrees(c.tilt)),
               "camera_tilt_azimuth_deg": float(np.degrees(c.tilt_azimuth)),
               "camera_roll_deg": float(np.degrees(c.roll))}
        for f, (dx, dy, da) in zip(FINGERS, self.overlay, strict=True):
            row |= {f"overlay_{f}_dx": float(dx), f"overlay_{f}_dy": float(dy),
                    f"overlay_{f}_rot_deg": float(np.degrees(da))}
        light = self.light
        row |= {"light_elevation_deg": float(np.degrees(light.elevation)) if light else nan,
                "light_azimuth_deg": float(np.degrees(light.azimuth)) if light else nan,
                "light_diffuse": float(light.diffuse) if light else nan,
                "light_ambient": float(light.ambient) if light else nan,
                "shadows": bool(self.shadows)}
        row |= {f"table_{ch}": float(v) for ch, v in zip("rgb", self.table_rgb, strict=True)}
        row["table_texture"] = float(self.texture.strength) if self.texture else 0.0
        return row


def _rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rotation matrix of `angle` rad about unit `axis` (Rodrigues)."""
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * (k @ k)


def rotz(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
