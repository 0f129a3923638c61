"""Where the simulator says the fingers touch the object: auxiliary training targets.

A generated dataset's ``configs.parquet`` holds, per configuration and finger, the contact point
on the object (``target_<finger>_x|y``, world metres), the object's outward surface normal
there (``normal_<finger>_x|y|z``, the finger's sensor frame) and the finger's direction
(``approach_<finger>_x|y``, world, the sensor's z axis). `contact_truth` turns them into what a
model reading the image can be taught: the contact point in pixels (u right, v down), the
normal as (n_y, n_z), the label's coordinates, and the finger's axis as an image direction.

The projection is the plain top view, ``u = (x - camera_x) * px_per_m + W / 2 - 0.5``,
``v = -(y - camera_y) * px_per_m + H / 2 - 0.5``: pixel centres at integers, as the located
fingertips and the crops have them (`vistac.dataset.schema.PIXEL_CENTRE`). A configuration
whose camera was rolled or tilted (columns ``camera_roll_deg``, ``camera_tilt_deg``), whose
drawn fingers were displaced (``overlay_<finger>_*``), or that lacks any of the columns (an
ingested recording) has no truth: its rows are NaN and `ContactTruth.known` is False there, so
the auxiliary losses skip it and training on force labels alone still works.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vistac.dataset import FINGERS, DatasetTables
from vistac.dataset.schema import PIXEL_CENTRE, normal_columns
from vistac_learn.data.variants import read_rgb


@dataclass(frozen=True)
class ContactTruth:
    """Contact geometry of every configuration of a dataset.

    Attributes:
        point: (N, F, 2) contact point in pixels (u, v), fingers in `FINGERS` order.
        normal: (N, F, 2) outward object normal at the contact, (n_y, n_z) of the finger's
            sensor frame (unit).
        axis: (N, F, 2) unit image direction (u, v) of the finger (its sensor's z axis).
        known: (N, F) whether all three are known.
    """

    point: np.ndarray
    normal: np.ndarray
    axis: np.ndarray
    known: np.ndarray


def _plain_projection(configs) -> np.ndarray:
    """(N,) rows drawn with the plain top view (no camera roll or tilt, fingers not moved)."""
    ok = np.ones(len(configs), bool)
    for col in configs.columns:
        if col in ("camera_roll_deg", "camera_tilt_deg") or col.startswith("overlay_"):
            v = configs[col].to_numpy(float)
            ok &= np.nan_to_num(v, nan=0.0) == 0.0
    return ok


def contact_truth(tables: DatasetTables) -> ContactTruth:
    """The contact points and normals of `tables` (NaN and unknown where the table lacks them)."""
    c = tables.configs
    n = len(c)
    point = np.full((n, len(FINGERS), 2), np.nan)
    normal = np.full((n, len(FINGERS), 2), np.nan)
    axis = np.full((n, len(FINGERS), 2), np.nan)
    need = ["camera_x", "camera_y", "px_per_m"]
    for f in FINGERS:
        need += [f"target_{f}_x", f"target_{f}_y", f"approach_{f}_x", f"approach_{f}_y",
                 *normal_columns(f)[1:]]
    if n and all(k in c for k in need):
        size = tables.render.get("image_size")
        h, w = (size, size) if size else read_rgb(tables.image_path(0)).shape[:2]
        s = c["px_per_m"].to_numpy(float)
        cx, cy = c["camera_x"].to_numpy(float), c["camera_y"].to_numpy(float)
        for i, f in enumerate(FINGERS):
            x, y = c[f"target_{f}_x"].to_numpy(float), c[f"target_{f}_y"].to_numpy(float)
            point[:, i] = np.stack([(x - cx) * s + w / 2, -(y - cy) * s + h / 2],
                                   axis=1) - PIXEL_CENTRE
            nv = c[normal_columns(f)[1:]].to_numpy(float)
            normal[:, i] = _unit(nv)
            ax = c[[f"approach_{f}_x", f"approach_{f}_y"]].to_numpy(float)
            axis[:, i] = _unit(ax * np.array([1.0, -1.0]))  # world y up, image v down
        plain = _plain_projection(c)
        point[~plain], normal[~plain], axis[~plain] = np.nan, np.nan, np.nan
    known = (np.isfinite(point).all(axis=2) & np.isfinite(normal).all(axis=2)
             & np.isfinite(axis).all(axis=2))
    return ContactTruth(point, normal, axis, known)


def _unit(v: np.ndarray) -> np.ndarray:
    """Rows of `v` scaled to length 1 (NaN where the length is 0)."""
    norm = np.linalg.norm(v, axis=1, keepdims=True)
    return np.where(norm > 1e-9, v / np.where(norm > 1e-9, norm, 1.0), np.nan)


__all__ = ["ContactTruth", "contact_truth"]
