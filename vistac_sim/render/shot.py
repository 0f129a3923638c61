"""The render request of one configuration: the sampled parameters of every image effect.

An image effect (`vistac_sim.effects`, stage ``image``) is ``effect(shot, rng) -> shot`` on a
`Shot`. A `Shot` holds only sampled parameters (kornia-style: a sample can be replayed exactly
from them); `vistac_sim.render.shot_render` turns it into pixels and into the finger boxes the
image really shows. With image effects, the configuration row gets the view's parameters
(`Shot.columns`), whose ``camera_x, camera_y, px_per_m`` describe the projection the image was
made with.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np

from vistac.dataset import FINGERS
from vistac.projection import Projection, overlay_columns
from vistac_sim.render.config import RenderCfg

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
        fovy: Vertical field of view of a perspective camera, rad; 0 is the orthographic view.
            A perspective camera stands as high above the table as makes the working area
            (the clean view's extent over `scale`) fill the frame at the table plane.
    """

    center: tuple[float, float] = (0.0, 0.0)
    scale: float = 1.0
    tilt: float = 0.0
    tilt_azimuth: float = 0.0
    roll: float = 0.0
    fovy: float = 0.0


@dataclass(frozen=True)
class Light:
    """A directional key light (angles in rad; colours are grey levels in [0, 1])."""

    elevation: float
    azimuth: float
    diffuse: float
    ambient: float
    specular: float = 0.0
    rgb: tuple[float, float, float] = (1.0, 1.0, 1.0)  # colour of the diffuse/specular light
    softness: float = 0.0  # soft shadow edges (MuJoCo's light `bulbradius`, m)

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
class Surface:
    """The look of a surface (the object or the table): a texture of the bank, a tint, shine.

    Attributes:
        kind: Texture kind of the bank (`vistac_sim.render.textures`), "" for none.
        pick: Which texture of that kind, in [0, 1) (scaled to the kind's number of textures).
        rgb: Tint in [0, 1] (the texture is multiplied by it; the colour without a texture).
        repeat: Texture repeats per metre.
        specular, shininess: MuJoCo's material shine, in [0, 1].
    """

    kind: str
    pick: float
    rgb: tuple[float, float, float]
    repeat: float = 10.0
    specular: float = 0.5
    shininess: float = 0.5


@dataclass(frozen=True)
class Finish:
    """Image-space camera effects on the rendered frame, applied in this order.

    Attributes:
        gain: Exposure and white balance: per-channel gain (R, G, B).
        defocus: Gaussian blur sigma, px (0: sharp).
        motion: (length px, direction rad) of a linear motion blur (length 0: none).
        noise: (read std, shot factor) of the sensor noise in grey levels: the std of a pixel
            of value I is sqrt(read^2 + shot * I).
        noise_at: (row, column) offset into the process's fixed bank of unit normals.
        jpeg: JPEG quality the frame is encoded and decoded at (0: none).
    """

    gain: tuple[float, float, float] = (1.0, 1.0, 1.0)
    defocus: float = 0.0
    motion: tuple[float, float] = (0.0, 0.0)
    noise: tuple[float, float] = (0.0, 0.0)
    noise_at: tuple[int, int] = (0, 0)
    jpeg: int = 0


@dataclass(frozen=True)
class DrawnStyle:
    """How a person draws the fingers into the photograph (in 2D, over the finished frame).

    Attributes:
        rgb: Per finger (index, thumb), fill colour in [0, 1].
        width: Per finger, the drawn width relative to the real finger's.
        outline: Outline thickness, px (0: none).
        outline_rgb: Outline colour in [0, 1].
        antialias: Anti-aliased edges, or hard ones.
        taper: Width of the drawn shaft's far end relative to the fingertip (1: capsules, as
            the finger is; < 1: one tapered outline from the tip to the shaft's end).
    """

    rgb: tuple[tuple[float, float, float], tuple[float, float, float]]
    width: tuple[float, float] = (1.0, 1.0)
    outline: float = 0.0
    outline_rgb: tuple[float, float, float] = (0.0, 0.0, 0.0)
    antialias: bool = True
    taper: float = 1.0


@dataclass(frozen=True)
class Shot:
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
        object_look: The object's texture, tint and shine, or None (its plain colour).
        table_look: The table's texture (its colour stays `table_rgb`), or None.
        finish: Image-space camera effects, or None.
        drawn: The fingers drawn by hand in 2D over the finished frame (the rendered fingers
            are hidden), or None (the rendered fingers).
    """

    image_size: int
    view_extent: float
    table_rgb: tuple[float, float, float]
    overlay: tuple[tuple[float, float, float], ...] = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    camera: CameraPose = field(default_factory=CameraPose)
    light: Light | None = None
    shadows: bool = False
    texture: TableTexture | None = None
    object_look: Surface | None = None
    table_look: Surface | None = None
    finish: Finish | None = None
    drawn: DrawnStyle | None = None

    @classmethod
    def of(cls, cfg: RenderCfg) -> Shot:
        """The clean view of a render config."""
        return cls(cfg.image_size, cfg.view_extent, tuple(cfg.table_rgb))

    @property
    def px_per_m(self) -> float:
        """Pixels per metre of this view."""
        return self.image_size / self.view_extent * self.camera.scale

    @functools.cached_property
    def projection(self) -> Projection:
        """The camera this shot is seen with (world to pixel; made once per shot)."""
        c = self.camera
        return Projection(self.image_size, self.px_per_m, c.center, c.tilt, c.tilt_azimuth,
                          c.roll, c.fovy)

    @property
    def perspective(self) -> bool:
        """True for a perspective camera (`CameraPose.fovy` > 0)."""
        return self.projection.perspective

    @property
    def distance(self) -> float:
        """The camera's distance from the table point at the image centre, m."""
        return self.projection.distance

    def frame(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(pos, right, up, forward) of the camera in world coordinates (`Projection.frame`)."""
        return self.projection.frame()

    def project(self, points: np.ndarray) -> np.ndarray:
        """Continuous pixel coordinates (u right, v down) of world points (..., 3)
        (`Projection.project`)."""
        return self.projection.project(points)

    def columns(self) -> dict:
        """The view's parameters as configuration-table columns (angles in degrees)."""
        nan = float("nan")
        row = self.projection.columns()
        for f, overlay in zip(FINGERS, self.overlay, strict=True):
            row |= overlay_columns(f, overlay)
        light = self.light
        row |= {"light_elevation_deg": float(np.degrees(light.elevation)) if light else nan,
                "light_azimuth_deg": float(np.degrees(light.azimuth)) if light else nan,
                "light_diffuse": float(light.diffuse) if light else nan,
                "light_ambient": float(light.ambient) if light else nan,
                "shadows": bool(self.shadows)}
        row |= {f"table_{ch}": float(v) for ch, v in zip("rgb", self.table_rgb, strict=True)}
        row["table_texture"] = float(self.texture.strength) if self.texture else 0.0
        return row | self._photo_columns()

    def _photo_columns(self) -> dict:
        """Columns of the appearance parameters that are set (none for a view without them)."""
        row: dict = self.projection.perspective_columns()
        if self.light is not None and self.light.rgb != (1.0, 1.0, 1.0):
            row |= {f"light_{ch}": float(v) for ch, v in zip("rgb", self.light.rgb, strict=True)}
        for name, look in (("object", self.object_look), ("table", self.table_look)):
            if look is not None:
                row |= {f"{name}_texture_kind": look.kind,
                        f"{name}_texture_pick": float(look.pick)}
                row |= {f"{name}_look_{ch}": float(v) for ch, v in zip("rgb", look.rgb,
                                                                         strict=True)}
        if self.finish is not None:
            f = self.finish
            row |= {f"gain_{ch}": float(v) for ch, v in zip("rgb", f.gain, strict=True)}
            row |= {"defocus_px": float(f.defocus), "motion_blur_px": float(f.motion[0]),
                    "noise_read": float(f.noise[0]), "noise_shot": float(f.noise[1]),
                    "jpeg_quality": int(f.jpeg)}
        if self.drawn is not None:
            d = self.drawn
            for f, rgb, w in zip(FINGERS, d.rgb, d.width, strict=True):
                row |= {f"drawn_{f}_{ch}": float(v) for ch, v in zip("rgb", rgb, strict=True)}
                row[f"drawn_{f}_width"] = float(w)
            row |= {"drawn_outline_px": float(d.outline), "drawn_antialias": bool(d.antialias),
                    "drawn_taper": float(d.taper)}
        return row
