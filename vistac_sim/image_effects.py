"""Image-stage effects: what the camera sees differs from the clean top view, the physics does not.

An image effect is ``effect(view, rng) -> view`` on a `View`, the render request of one
configuration. A `View` holds only sampled parameters (kornia-style: a sample can be replayed
exactly from them); `render_view` turns it into pixels and `view_boxes` into the finger boxes the
image really shows. Everything a view changes is applied to MuJoCo's *visual scene* (`MjvScene`)
between ``update_scene`` and ``render``, so the model and the physics state are never touched and
nothing needs restoring:

- overlay error: the pad and shaft geoms of each drawn finger are moved and turned about the
  fingertip (the drawn finger misses where the finger really was) and, like the study's fingers
  painted into the photograph, drawn on top of everything without a shadow (moved towards the
  camera along its view axis, which leaves their pixels where they are);
- camera jitter: the GL camera is shifted, scaled, tilted off vertical and rolled;
- lighting: the headlight keeps only its ambient part and a directional key light is added;
- shadows: that key light casts shadows (needs a shadow map, created with the renderer only for
  scenes that ask for shadows: `shadow_map_size`);
- table: the table's colour, and a brightness pattern multiplied onto the table's pixels (found
  with a segmentation render of the same scene).

Without image effects `sample.make_configuration` keeps the plain render path; with them the
configuration row gets the view's parameters (`View.columns`), whose ``camera_x, camera_y,
px_per_m`` describe the projection the image was made with.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field, replace
from typing import ClassVar

import cv2
import mujoco
import numpy as np

from vistac_sim.config import EffectsCfg, RenderCfg
from vistac_sim.effects import Effect, Pipeline
from vistac_sim.render import TopView, boxes_from_outlines, finger_capsules
from vistac_sim.scene import FINGERS, SceneIds

CAMERA_DISTANCE = 1.0  # m, the scene camera's height above the table (scene.py)
OVERLAY_LIFT = 0.2  # m a drawn finger is moved towards the camera (in front of any object)
GEOM = int(mujoco.mjtObj.mjOBJ_GEOM)  # a plain int: comparing arrays with the enum is slow
_HEADLIGHT = (0.45, 0.55)  # ambient, diffuse of the scene's headlight (scene.py)


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


def _rotz(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


# ------------------------------------------------------------------------------- the effects
@dataclass(frozen=True)
class OverlayError(Effect):
    """The drawn fingers miss where the fingers really were (image and boxes only)."""

    name: ClassVar[str] = "overlay_error"
    stage: ClassVar[str] = "image"
    offset_std: float = 0.002
    rotation_std_deg: float = 3.0
    offset: tuple[float, float] = (0.0, 0.0)
    rotation_deg: float = 0.0

    def __call__(self, view: View, rng: np.random.Generator) -> View:
        shift = np.asarray(self.offset, float) + rng.normal(0.0, 1.0, (2, 2)) * self.offset_std
        turn = np.radians(self.rotation_deg + rng.normal(0.0, 1.0, 2) * self.rotation_std_deg)
        overlay = tuple((float(d[0]), float(d[1]), float(a)) for d, a in zip(shift, turn,
                                                                              strict=True))
        return replace(view, overlay=overlay)


@dataclass(frozen=True)
class CameraJitter(Effect):
    """Small shift, scale, tilt and roll of the top camera per configuration."""

    name: ClassVar[str] = "camera_jitter"
    stage: ClassVar[str] = "image"
    shift_std: float = 0.003
    scale_std: float = 0.02
    tilt_std_deg: float = 1.0
    roll_std_deg: float = 1.0

    def __call__(self, view: View, rng: np.random.Generator) -> View:
        shift = rng.normal(0.0, self.shift_std, 2)
        scale = float(np.exp(rng.normal(0.0, self.scale_std)))
        tilt_xy = np.radians(rng.normal(0.0, self.tilt_std_deg, 2))  # per horizontal axis
        roll = float(np.radians(rng.normal(0.0, self.roll_std_deg)))
        cx, cy = view.camera.center
        camera = CameraPose((cx + float(shift[0]), cy + float(shift[1])),
                            view.camera.scale * scale, float(np.hypot(*tilt_xy)),
                            float(np.arctan2(tilt_xy[1], tilt_xy[0])), view.camera.roll + roll)
        return replace(view, camera=camera)


@dataclass(frozen=True)
class Lighting(Effect):
    """A directional key light of random direction and intensity."""

    name: ClassVar[str] = "lighting"
    stage: ClassVar[str] = "image"
    elevation_deg: tuple[float, float] = (35.0, 80.0)
    azimuth_deg: tuple[float, float] = (0.0, 360.0)
    intensity: tuple[float, float] = (0.4, 0.8)
    ambient: tuple[float, float] = (0.3, 0.55)
    specular: float = 0.2

    def __call__(self, view: View, rng: np.random.Generator) -> View:
        el, az, diffuse, ambient = (rng.uniform(*r) for r in (
            self.elevation_deg, self.azimuth_deg, self.intensity, self.ambient))
        return replace(view, light=Light(float(np.radians(el)), float(np.radians(az)),
                                         float(diffuse), float(ambient), self.specular))


@dataclass(frozen=True)
class Shadows(Effect):
    """The key light casts shadows (a fixed key light when the lighting effect is off).

    The fixed key light keeps the lit table as bright as under the plain headlight: ambient
    0.45, diffuse 0.55 / sin(elevation) (at most 1).
    """

    name: ClassVar[str] = "shadows"
    stage: ClassVar[str] = "image"
    map_size: int = 2048
    elevation_deg: float = 55.0
    azimuth_deg: float = 30.0

    def __call__(self, view: View, rng: np.random.Generator) -> View:
        light = view.light
        if light is None:
            el = np.radians(self.elevation_deg)
            light = Light(float(el), float(np.radians(self.azimuth_deg)),
                          float(min(1.0, _HEADLIGHT[1] / np.sin(el))), _HEADLIGHT[0])
        return replace(view, light=light, shadows=True)


@dataclass(frozen=True)
class Table(Effect):
    """Table colour per configuration and a brightness pattern (texture) on it."""

    name: ClassVar[str] = "table"
    stage: ClassVar[str] = "image"
    rgb_std: float = 0.05
    texture: float = 0.04
    texture_scale: float = 0.004
    texture_octaves: int = 3

    def __call__(self, view: View, rng: np.random.Generator) -> View:
        rgb = np.clip(np.asarray(view.table_rgb) + rng.normal(0.0, self.rgb_std, 3), 0.0, 1.0)
        seed = int(rng.integers(2**31))
        texture = TableTexture(seed, self.texture, self.texture_scale, self.texture_octaves) \
            if self.texture > 0 else None
        return replace(view, table_rgb=tuple(float(v) for v in rgb), texture=texture)


IMAGE_EFFECTS: dict[str, type[Effect]] = {
    "overlay_error": OverlayError,
    "camera_jitter": CameraJitter,
    "lighting": Lighting,
    "shadows": Shadows,
    "table": Table,
}


def image_effect(key: str, cfg) -> Effect:
    """The image effect of `EffectsCfg` field `key`, built from that field's config."""
    return IMAGE_EFFECTS[key](**dataclasses.asdict(cfg))


def shadow_map_size(cfg: EffectsCfg) -> int:
    """Shadow map texels the renderer needs: 0 unless the shadows effect is on."""
    return int(cfg.shadows.map_size) if getattr(cfg, "shadows", None) is not None else 0


# ------------------------------------------------------------------------------- rendering
def render_with_effects(top: TopView, data: mujoco.MjData, pipeline: Pipeline, cfg: RenderCfg,
                        rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, dict]:
    """Run the image effects on the clean view, then render it.

    Returns:
        (RGB image, (2, 4) boxes of the drawn fingers as the image shows them, the view's
        configuration-table columns).
    """
    view = pipeline.apply_image(View.of(cfg), rng)
    return (render_view(top, data, view), view_boxes(top.model, data, top.ids, view),
            view.columns())


def render_view(top: TopView, data: mujoco.MjData, view: View,
                segmentation: bool = False) -> np.ndarray:
    """RGB image (H, W, 3) uint8 of the current state as `view` sees it (or the segmentation).

    Raises:
        ValueError: the view asks for shadows from a renderer made without a shadow map.
    """
    if view.shadows and top.model.vis.quality.shadowsize <= 0:
        raise ValueError("shadows need a renderer made with a shadow map (shadow_map_size)")
    r = top.renderer
    r.update_scene(data, camera=top.ids.camera, scene_option=top.option)
    table = _apply_view(r.scene, top.model, data, top.ids, view)
    if segmentation:
        return _segmentation(r)
    rgb = r.render()
    if view.texture is not None:
        seg = _segmentation(r)
        mask = (seg[..., 1] == GEOM) & (seg[..., 0] == table)
        gain = texture_pattern(view.texture, view.image_size, view.px_per_m)
        shaded = np.clip(rgb * np.where(mask, gain, 1.0)[..., None], 0, 255)
        rgb = np.rint(shaded).astype(np.uint8)
    return rgb


def _segmentation(renderer: mujoco.Renderer) -> np.ndarray:
    renderer.enable_segmentation_rendering()
    try:
        return renderer.render()
    finally:
        renderer.disable_segmentation_rendering()


def _apply_view(scn: mujoco.MjvScene, model: mujoco.MjModel, data: mujoco.MjData, ids: SceneIds,
                view: View) -> int:
    """Change the visual scene as `view` asks; returns the table's geom id."""
    table = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "table")
    pos, right, up, fwd = view.frame()
    lift = -OVERLAY_LIFT * fwd  # towards the camera: same pixels, in front of everything
    moves = {}
    for f, (dx, dy, da) in zip(FINGERS, view.overlay, strict=True):
        if dx or dy or da:
            pivot = data.site_xpos[ids.site[f]].copy()
            for g in (ids.pad[f], ids.shaft[f]):
                moves[g] = (pivot, _rotz(da), np.array([dx, dy, 0.0]))
    for i in range(scn.ngeom):
        g = scn.geoms[i]
        if g.objtype != GEOM:
            continue
        if g.objid in moves:  # a drawn finger: painted over the scene, without a shadow
            pivot, rot, shift = moves[g.objid]
            g.pos[:] = pivot + rot @ (np.asarray(g.pos, float) - pivot) + shift + lift
            g.mat[:] = rot @ np.asarray(g.mat, float)
            g.castshadow = 0
        elif g.objid == table:
            g.rgba[:3] = view.table_rgb
    half = view.image_size / view.px_per_m / 2
    for cam in scn.camera:  # both eyes at the same place: a mono orthographic view
        cam.pos[:], cam.forward[:], cam.up[:] = pos, fwd, up
        cam.frustum_center, cam.frustum_top, cam.frustum_bottom = 0.0, half, -half
    if view.light is not None:
        _add_key_light(scn, view)
    return table


def _add_key_light(scn: mujoco.MjvScene, view: View) -> None:
    light = view.light
    for i in range(scn.nlight):
        if scn.lights[i].headlight:
            h = scn.lights[i]
            h.ambient[:], h.diffuse[:], h.specular[:] = light.ambient, 0.0, 0.0
    if scn.nlight >= len(scn.lights):
        raise RuntimeError("no room for the key light in the visual scene")
    key = scn.lights[scn.nlight]
    scn.nlight += 1
    key.type = mujoco.mjtLightType.mjLIGHT_DIRECTIONAL
    key.headlight = 0
    key.dir[:] = light.direction
    key.pos[:] = (*view.camera.center, 0.0)  # directional: centre of the shadow map
    key.ambient[:], key.diffuse[:], key.specular[:] = 0.0, light.diffuse, light.specular
    key.attenuation[:] = (1.0, 0.0, 0.0)
    key.castshadow = int(view.shadows)


def texture_pattern(texture: TableTexture, size: int, px_per_m: float) -> np.ndarray:
    """(size, size) brightness gain 1 + strength * (unit-std fractal noise), at least 0."""
    rng = np.random.default_rng(texture.seed)
    noise = np.zeros((size, size))
    for octave in range(max(1, texture.octaves)):
        cell = max(texture.scale * px_per_m / 2**octave, 1.0)
        n = int(np.ceil(size / cell)) + 3
        grid = rng.standard_normal((n, n)).astype(np.float32)
        up = cv2.resize(grid, (int(round(n * cell)),) * 2, interpolation=cv2.INTER_CUBIC)
        noise += up[:size, :size] * 0.5**octave
    noise = (noise - noise.mean()) / max(noise.std(), 1e-12)
    return np.maximum(1.0 + texture.strength * noise, 0.0)


def view_boxes(model: mujoco.MjModel, data: mujoco.MjData, ids: SceneIds,
               view: View) -> np.ndarray:
    """(2, 4) pixel boxes (x, y, w, h; top-left origin) of the visible part of each finger as
    `view` draws it.

    As `render.finger_boxes` (which it equals for the clean view), for any camera pose and
    overlay error: each capsule is moved by the overlay, its end points are projected, and the
    segment between them widened by the radius in pixels is its outline (an orthographic view
    draws a sphere as a circle of the same radius); the box bounds the union of a finger's
    outlines clipped to the image. Under a tilted camera the top of a tall object may hide a
    sliver of a (not overlaid) finger; the box still holds the finger's whole outline.
    """
    s = view.px_per_m
    caps_px = []
    for k, (f, caps) in enumerate(zip(FINGERS, finger_capsules(model, data, ids), strict=True)):
        dx, dy, da = view.overlay[k]
        pivot, rot = data.site_xpos[ids.site[f]], _rotz(da)
        moved = []
        for a, b, r in caps:
            ends = pivot + (np.array([a, b]) - pivot) @ rot.T + np.array([dx, dy, 0.0])
            p0, p1 = view.project(ends)
            moved.append((p0, p1, r * s))
        caps_px.append(moved)
    return boxes_from_outlines(caps_px, view.image_size)
