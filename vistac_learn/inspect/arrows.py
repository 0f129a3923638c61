"""Where each fingertip is in an image and which way its labelled force points there.

A label (r_y, r_z) lives in the finger's sensor frame; `vistac.dataset.frames.sensor_to_image`
turns it into an image direction given the finger's axis in the image. The fingertip and its
axis come from the simulator's columns (`fingertip_table.simulator_tips`: the exact projection)
when the dataset has them, else from the fingertip locator on the image (ingested datasets).
The arrow is the force the object exerts on the fingertip (what the sensor measures), drawn from
the fingertip's centre: against the finger's approach, tilted by the label's y.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vistac.dataset import FINGERS
from vistac.dataset.frames import sensor_to_image
from vistac.dataset.reader import DatasetTables


@dataclass(frozen=True)
class FingerArrows:
    """One finger of one configuration, in image pixels (u right, v down, centres at integers).

    Attributes:
        tip: (2,) fingertip centre.
        axis: (2,) unit finger axis (back -> tip), the sensor's z.
        mean: (2,) unit image direction of the mean label, or None without labels.
        presses: (K, 2) unit image directions of the presses (the cone).
        source: ``simulator`` or ``located``.
    """

    tip: np.ndarray
    axis: np.ndarray
    mean: np.ndarray | None
    presses: np.ndarray
    source: str


def mean_label(cone: np.ndarray) -> np.ndarray | None:
    """The renormalised mean of a configuration's unit labels (K, 2); None when K is 0,
    (0, -1) when the mean is 0 (as the dataset labels a zero force)."""
    if len(cone) == 0:
        return None
    m = np.asarray(cone, float).mean(axis=0)
    n = float(np.hypot(*m))
    return m / n if n > 1e-12 else np.array([0.0, -1.0])


def has_simulator_tips(tables: DatasetTables) -> bool:
    """Whether the configurations carry the simulator's fingertips and axes (finite)."""
    cols = [f"{k}_{f}_{a}" for f in FINGERS for k in ("tip", "approach") for a in "xy"]
    cols += ["camera_x", "camera_y", "px_per_m"]
    if not set(cols) <= set(tables.configs.columns):
        return False
    return bool(np.isfinite(tables.configs[cols].to_numpy(float)).all())


def finger_arrows(tables: DatasetTables, row: int, rgb: np.ndarray | None,
                  simulated: bool) -> dict[str, FingerArrows | None]:
    """The arrows of each finger of configuration `row` (None: the finger was not found).

    Args:
        tables: The dataset (a salvaged one too: its cones may be empty).
        row: Configuration row.
        rgb: The image (H, W, 3) uint8; needed to locate the fingers when not `simulated`.
        simulated: Take the tips from the simulator's columns (`has_simulator_tips`).
    """
    if simulated:
        from vistac_learn.data.fingertip_table import simulator_tips

        size = int(rgb.shape[1]) if rgb is not None else int(tables.render.get("image_size", 227))
        tips = {f: (t, a, "simulator") for f, (t, a) in simulator_tips(tables, row, size).items()}
    elif rgb is not None:
        from vistac_learn.data.locator import locate_fingertips

        found = locate_fingertips(rgb, {f: tables.finger_rgb(f) for f in FINGERS})
        tips = {f: (t.tip, t.axis, "located") for f, t in found.items() if t.ok}
    else:
        tips = {}
    out: dict[str, FingerArrows | None] = {}
    for f in FINGERS:
        if f not in tips:
            out[f] = None
            continue
        tip, axis, source = tips[f]
        cone = tables.cones[f][row] if row < len(tables.cones.get(f, [])) else np.zeros((0, 2))
        m = mean_label(cone)
        out[f] = FingerArrows(np.asarray(tip, float), np.asarray(axis, float),
                              None if m is None else sensor_to_image(m, axis, f),
                              sensor_to_image(cone, axis, f).reshape(-1, 2), source)
    return out
