"""Orthographic top view with MuJoCo's own renderer, and exact finger boxes in pixels.

World -> pixel (camera centred on the world origin, looking straight down):
``u = X * px_per_m + W / 2``, ``v = -Y * px_per_m + H / 2`` (image y points down).
"""

from __future__ import annotations

import cv2
import mujoco
import numpy as np

from vistac_sim.config import RenderCfg
from vistac_sim.scene import FINGERS, OBJECT_GROUP_COLLISION, SceneIds


class TopView:
    """Renders one compiled scene from its top camera. Create it inside the worker process."""

    def __init__(self, model: mujoco.MjModel, ids: SceneIds, cfg: RenderCfg, shadow_size: int = 0):
        self.model, self.ids, self.cfg = model, ids, cfg
        model.vis.quality.shadowsize = shadow_size  # shadow map texels; 0: no shadow pass
        self.renderer = mujoco.Renderer(model, cfg.image_size, cfg.image_size)
        self.option = mujoco.MjvOption()
        self.option.geomgroup[OBJECT_GROUP_COLLISION] = 0
        self.option.sitegroup[:] = 0

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


def px_per_m(cfg: RenderCfg) -> float:
    """Pixels per metre of the top view."""
    return cfg.image_size / cfg.view_extent


def world_to_pixel(xy: np.ndarray, cfg: RenderCfg) -> np.ndarray:
    """Continuous pixel coordinates (u right, v down) of world points (..., 2)."""
    s, half = px_per_m(cfg), cfg.image_size / 2
    xy = np.asarray(xy, float)
    return np.stack([xy[..., 0] * s + half, -xy[..., 1] * s + half], axis=-1)


def finger_boxes(model: mujoco.MjModel, data: mujoco.MjData, ids: SceneIds,
                 cfg: RenderCfg) -> np.ndarray:
    """(2, 4) exact pixel boxes (x, y, w, h; top-left origin) of the drawn index and thumb.

    Boxes are clipped to the image, so they hold the visible part of each finger.

    Each finger is the union of its capsules (pad and shaft); a capsule's top-view outline is
    bounded by its two end points widened by its radius.
    """
    boxes = np.zeros((2, 4))
    for k, f in enumerate(FINGERS):
        pts, rad = [], []
        for g in (ids.pad[f], ids.shaft[f]):
            axis = data.geom_xmat[g].reshape(3, 3)[:, 2] * model.geom_size[g, 1]
            pts += [data.geom_xpos[g] + axis, data.geom_xpos[g] - axis]
            rad += [model.geom_size[g, 0]] * 2
        pts, rad = np.array(pts)[:, :2], np.array(rad)[:, None]
        lo_xy, hi_xy = (pts - rad).min(0), (pts + rad).max(0)
        u0, v1 = world_to_pixel(lo_xy, cfg)
        u1, v0 = world_to_pixel(hi_xy, cfg)
        u0, v0 = max(u0, 0.0), max(v0, 0.0)  # clip to the image: the visible part
        u1, v1 = min(u1, cfg.image_size), min(v1, cfg.image_size)
        boxes[k] = [u0, v0, max(u1 - u0, 0.0), max(v1 - v0, 0.0)]
    return boxes


def encode_png(rgb: np.ndarray) -> bytes:
    """Fast, deterministic PNG encoding of an RGB image."""
    ok, buf = cv2.imencode(".png", rgb[:, :, ::-1], [cv2.IMWRITE_PNG_COMPRESSION, 1])
    if not ok:
        raise RuntimeError("PNG encoding failed")
    return buf.tobytes()
