"""Orthographic top view with MuJoCo's own renderer, and exact finger boxes in pixels.

World -> pixel (camera centred on the world origin, looking straight down):
``u = X * px_per_m + W / 2``, ``v = -Y * px_per_m + H / 2`` (image y points down).
"""

from __future__ import annotations

import numpy as np

from vistac.dataset import FINGERS
from vistac.errors import UserError
from vistac_sim.hand.ids import OBJECT_GROUP_COLLISION, ModelIds
from vistac_sim.mj import gl_context, gl_error, mujoco
from vistac_sim.render.boxes import boxes_from_outlines
from vistac_sim.render.config import RenderCfg
from vistac_sim.render.materials import texture_ids


class TopView:
    """Renders one compiled scene from its top camera. Create it inside the worker process."""

    def __init__(self, model: mujoco.MjModel, ids: ModelIds, cfg: RenderCfg, shadow_size: int = 0):
        self.model, self.ids, self.cfg = model, ids, cfg
        model.vis.quality.shadowsize = shadow_size  # shadow map texels; 0: no shadow pass
        self.renderer = SharedContextRenderer(model, cfg.image_size)
        self.option = mujoco.MjvOption()
        self.option.geomgroup[OBJECT_GROUP_COLLISION] = 0
        self.option.sitegroup[:] = 0
        self.texture_ids = texture_ids(model)  # bank -> kind -> ids (empty: no textures)

    def render(self, data: mujoco.MjData, segmentation: bool = False) -> np.ndarray:
        """RGB image (H, W, 3) uint8 of the current state (or geom-id segmentation)."""
        if segmentation:
            self.renderer.enable_segmentation_rendering()
        self.renderer.update_scene(data, camera=self.ids.camera, scene_option=self.option)
        img = self.renderer.render()
        if segmentation:
            self.renderer.disable_segmentation_rendering()
        return img

    def close(self) -> None:
        self.renderer.close()


_GL_CONTEXTS: dict[int, object] = {}  # this process's GL context per image size


class SharedContextRenderer(mujoco.Renderer):
    """`mujoco.Renderer` of a square image drawing in this process's one GL context.

    MuJoCo's renderer makes a GL context per instance and a visual scene of 10000 geoms; a
    worker keeps one renderer per object, and making those cost ~50 ms and ~20 MB per object.
    This one shares a GL context per process (each model still gets its own `MjrContext`, the
    models' meshes and textures on the GPU) and sizes the visual scene to the model. Mirrors
    ``mujoco.Renderer.__init__`` and ``close`` of the pinned MuJoCo (4.0.1); rendering is
    inherited unchanged, so the pixels are the same (tested against `mujoco.Renderer`).
    """

    def __init__(self, model: mujoco.MjModel, size: int) -> None:  # noqa: D107
        self._gl_context, self._mjr_context = None, None
        if size > min(model.vis.global_.offwidth, model.vis.global_.offheight):
            raise ValueError(f"image size {size} exceeds the model's offscreen framebuffer")
        self._width = self._height = size
        self._model = model
        # Every model geom, plus room for the few decorations a view may add.
        self._scene = mujoco.MjvScene(model=model, maxgeom=model.ngeom + 64)
        self._scene_option = mujoco.MjvOption()
        self._rect = mujoco.MjrRect(0, 0, size, size)
        try:
            if gl_context.GLContext is not None:
                if size not in _GL_CONTEXTS:
                    _GL_CONTEXTS[size] = gl_context.GLContext(size, size)
                self._gl_context = _GL_CONTEXTS[size]
                self._gl_context.make_current()
            self._mjr_context = mujoco.MjrContext(model,
                                                  mujoco.mjtFontScale.mjFONTSCALE_150.value)
        except Exception as exc:  # noqa: BLE001 - FatalError (no GL platform), GL errors
            raise UserError(gl_error(" ".join(str(exc).split()) or type(exc).__name__)) from None
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN.value, self._mjr_context)
        self._mjr_context.readDepthMap = mujoco.mjtDepthMap.mjDEPTH_ZEROFAR
        self._depth_rendering = self._segmentation_rendering = False

    def render(self, *, out: np.ndarray | None = None) -> np.ndarray:
        """As `mujoco.Renderer.render`, after binding this model's offscreen buffer."""
        if self._gl_context is not None and self._mjr_context is not None:
            self._gl_context.make_current()
            mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN.value, self._mjr_context)
        return super().render(out=out)

    def close(self) -> None:
        """Free this model's GPU resources; the shared GL context stays for the next one."""
        if self._mjr_context:
            if self._gl_context:
                self._gl_context.make_current()
            self._mjr_context.free()
        self._mjr_context = None
        self._gl_context = None

    def __del__(self) -> None:
        try:
            self.close()
        except Exception:  # noqa: BLE001 - at interpreter exit EGL may already be torn down
            pass


def px_per_m(cfg: RenderCfg) -> float:
    """Pixels per metre of the top view."""
    return cfg.image_size / cfg.view_extent


def world_to_pixel(xy: np.ndarray, cfg: RenderCfg) -> np.ndarray:
    """Continuous pixel coordinates (u right, v down) of world points (..., 2)."""
    s, half = px_per_m(cfg), cfg.image_size / 2
    xy = np.asarray(xy, float)
    return np.stack([xy[..., 0] * s + half, -xy[..., 1] * s + half], axis=-1)


Point = tuple[float, float, float]


def finger_capsules(model: mujoco.MjModel, data: mujoco.MjData,
                    ids: ModelIds) -> list[list[tuple[Point, Point, float]]]:
    """Per finger, its capsules (pad, shaft) as (end, end, radius) in world coordinates, in
    plain floats (a handful of numbers, read once per image)."""
    geoms = [g for f in FINGERS for g in (ids.pad[f], ids.shaft[f])]  # (finger, capsule) order
    pos = data.geom_xpos[geoms].tolist()
    zax = data.geom_xmat[geoms][:, 2::3].tolist()  # each capsule's axis (its z), world frame
    size = model.geom_size[geoms].tolist()
    caps = []
    for (x, y, z), (ax, ay, az), (r, half_len, _) in zip(pos, zax, size, strict=True):
        ax, ay, az = ax * half_len, ay * half_len, az * half_len
        caps.append(((x + ax, y + ay, z + az), (x - ax, y - ay, z - az), r))
    return [caps[:2], caps[2:]]


def finger_boxes(model: mujoco.MjModel, data: mujoco.MjData, ids: ModelIds,
                 cfg: RenderCfg) -> np.ndarray:
    """(2, 4) pixel boxes (x, y, w, h; top-left origin) of the visible part of each finger.

    A finger's top-view outline is the union of its capsules (pad and shaft), each a segment
    widened by its radius; the box is that outline clipped to the image, computed exactly.
    """
    s, half = px_per_m(cfg), cfg.image_size / 2
    caps = [[((a[0] * s + half, -a[1] * s + half), (b[0] * s + half, -b[1] * s + half), r * s)
             for a, b, r in finger] for finger in finger_capsules(model, data, ids)]
    return boxes_from_outlines(caps, cfg.image_size)
