"""Where the simulator says the fingers touch the object: auxiliary training targets.

A generated dataset's ``configs.parquet`` holds, per configuration and finger, the contact point
on the object (``target_<finger>_x|y``, world metres), the object's outward surface normal
there (``normal_<finger>_x|y|z``, the finger's sensor frame) and the finger's direction
(``approach_<finger>_x|y``, world, the sensor's z axis). `contact_truth` turns them into what a
model reading the image can be taught: the contact point in pixels (u right, v down), the
normal as (n_y, n_z), the label's coordinates, and the finger's axis as an image direction.

The contact point and the finger lie at the fingertips' height above the table
(the manifest's ``hand.height``) and are projected by the camera the image was made with
(`vistac.projection.Projection.from_columns`: the plain top view, a tilted or rolled one, or
the `photo` preset's perspective phone camera), pixel centres at integers as the located
fingertips and the crops have them (`vistac.dataset.schema.PIXEL_CENTRE`). The truth is the real
contact and the real finger, where the drawn finger was displaced too (``overlay_<finger>_*``):
the label is felt in the real finger's frame, and the model learns the drawn finger's offset
(the crop's tilt). A configuration that lacks any of the columns (an ingested recording) has no
truth: its rows are NaN and `ContactTruth.known` is False there, so the auxiliary losses skip it
and training on force labels alone still works.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vistac.dataset import FINGERS, DatasetTables
from vistac.dataset.schema import PIXEL_CENTRE, normal_columns
from vistac.projection import CAMERA_COLUMNS, CENTRE_COLUMNS, Projection
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


def contact_truth(tables: DatasetTables) -> ContactTruth:
    """The contact points and normals of `tables` (NaN and unknown where the table lacks them)."""
    c = tables.configs
    n = len(c)
    point = np.full((n, len(FINGERS), 2), np.nan)
    normal = np.full((n, len(FINGERS), 2), np.nan)
    axis = np.full((n, len(FINGERS), 2), np.nan)
    need = list(CENTRE_COLUMNS)
    for f in FINGERS:
        need += [f"target_{f}_x", f"target_{f}_y", f"approach_{f}_x", f"approach_{f}_y",
                 *normal_columns(f)[1:]]
    if n and all(k in c for k in need):
        size = tables.render.get("image_size") or read_rgb(tables.image_path(0)).shape[0]
        z = float(tables.hand.get("height", 0.0))
        cams = c[[k for k in CAMERA_COLUMNS if k in c]].to_dict("records")
        at = np.stack([np.stack([c[f"target_{f}_x"].to_numpy(float),
                                 c[f"target_{f}_y"].to_numpy(float), np.full(n, z)], axis=1)
                       for f in FINGERS], axis=1)  # (N, F, 3) world
        step = np.stack([np.stack([c[f"approach_{f}_x"].to_numpy(float),
                                   c[f"approach_{f}_y"].to_numpy(float), np.zeros(n)], axis=1)
                         for f in FINGERS], axis=1)
        for row, cam in enumerate(cams):
            proj = Projection.from_columns(cam, size)
            point[row] = proj.project(at[row]) - PIXEL_CENTRE
            axis[row] = proj.direction(at[row], step[row])
        for i, f in enumerate(FINGERS):
            normal[:, i] = _unit(c[normal_columns(f)[1:]].to_numpy(float))
            axis[:, i] = _unit(axis[:, i])
    known = (np.isfinite(point).all(axis=2) & np.isfinite(normal).all(axis=2)
             & np.isfinite(axis).all(axis=2))
    return ContactTruth(point, normal, axis, known)


def _unit(v: np.ndarray) -> np.ndarray:
    """Rows of `v` scaled to length 1 (NaN where the length is 0)."""
    norm = np.linalg.norm(v, axis=1, keepdims=True)
    return np.where(norm > 1e-9, v / np.where(norm > 1e-9, norm, 1.0), np.nan)


__all__ = ["ContactTruth", "contact_truth"]
