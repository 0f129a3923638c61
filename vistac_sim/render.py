"""Orthographic top view with MuJoCo's own renderer, and exact finger boxes in pixels.

World -> pixel (camera centred on the world origin, looking straight down):
``u = X * px_per_m + W / 2``, ``v = -Y * px_per_m + H / 2`` (image y points down).
"""

from __future__ import annotations

import struct
import zlib

import mujoco
import numpy as np
import shapely
from shapely.geometry import LineString
from shapely.ops import unary_union

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
    """(2, 4) pixel boxes (x, y, w, h; top-left origin) of the visible part of each finger.

    A finger's top-view outline is the union of its capsules (pad and shaft), each a segment
    widened by its radius; the box is that outline clipped to the image (outlines drawn with 64
    segments per circle: within 0.02 px of the exact box).
    """
    s = px_per_m(cfg)
    image = shapely.box(0, 0, cfg.image_size, cfg.image_size)
    boxes = np.zeros((2, 4))
    for k, f in enumerate(FINGERS):
        shapes = []
        for g in (ids.pad[f], ids.shaft[f]):
            axis = data.geom_xmat[g].reshape(3, 3)[:, 2] * model.geom_size[g, 1]
            ends = world_to_pixel(np.array([data.geom_xpos[g] + axis, data.geom_xpos[g] - axis])
                                  [:, :2], cfg)
            shapes.append(LineString(ends).buffer(model.geom_size[g, 0] * s, quad_segs=16))
        visible = unary_union(shapes).intersection(image)
        if not visible.is_empty:
            u0, v0, u1, v1 = visible.bounds
            boxes[k] = [u0, v0, u1 - u0, v1 - v0]
    return boxes


def encode_png(rgb: np.ndarray, level: int = 1) -> bytes:
    """Deterministic PNG bytes of an RGB image (8-bit, no filter, zlib `level`).

    Written with zlib directly: about twice as fast as OpenCV's encoder on these images.
    """
    h, w, _ = rgb.shape
    raw = np.zeros((h, w * 3 + 1), np.uint8)  # each row: filter byte 0, then RGB
    raw[:, 1:] = rgb.reshape(h, -1)
    return b"".join([
        b"\x89PNG\r\n\x1a\n",
        _png_chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)),
        _png_chunk(b"IDAT", zlib.compress(raw.tobytes(), level)),
        _png_chunk(b"IEND", b""),
    ])


def _png_chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
