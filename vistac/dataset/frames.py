"""A fingertip's sensor frame seen in the image: directions between image (u, v) and (y, z).

docs/dataset-format.md: a finger's sensor z points along the finger's axis (out of the pad,
towards the object), its y lies in the table plane across the finger: for the index finger the
axis turned 90 degrees counter-clockwise seen from above (world x right, y up), for the thumb
mirrored (turned clockwise). The image runs u right and v down, so in image coordinates the
index finger's y is the axis turned clockwise on the screen: axis (a_u, a_v) -> y (a_v, -a_u).
The in-image part of a label (r_y, r_z) is r_y y + r_z a (the sensor's x is perpendicular to
the image and dropped, as the label drops it).

This module is the one owner of that convention for image directions: the geometric baseline
reads a direction in the image as a label (`image_to_sensor`), `vistac inspect` draws a label
in the image (`sensor_to_image`).
"""

from __future__ import annotations

import numpy as np

from vistac.dataset.schema import FINGERS


def sensor_y_axis(axis: np.ndarray, finger: str) -> np.ndarray:
    """(..., 2) the sensor's y axis in image (u, v) coordinates of a finger whose axis (back of
    the finger -> tip, the sensor's z) is `axis` (..., 2), unit, image coordinates."""
    if finger not in FINGERS:
        raise ValueError(f"finger {finger!r} is not one of {', '.join(FINGERS)}")
    a = np.asarray(axis, float)
    y = np.stack([a[..., 1], -a[..., 0]], axis=-1)
    return y if finger == "index" else -y


def sensor_to_image(label: np.ndarray, axis: np.ndarray, finger: str) -> np.ndarray:
    """(..., 2) image (u, v) direction of labels (r_y, r_z) (..., 2) of a finger with image
    axis `axis` (2,) or (..., 2)."""
    lab, a = np.asarray(label, float), np.asarray(axis, float)
    return lab[..., :1] * sensor_y_axis(a, finger) + lab[..., 1:2] * a


def image_to_sensor(direction: np.ndarray, axis: np.ndarray, finger: str) -> np.ndarray:
    """(..., 2) (r_y, r_z) components of image (u, v) directions (..., 2) in the sensor frame of
    a finger with image axis `axis` (the inverse of `sensor_to_image` on unit vectors)."""
    d, a = np.asarray(direction, float), np.asarray(axis, float)
    y = sensor_y_axis(a, finger)
    return np.stack([(d * y).sum(axis=-1), (d * a).sum(axis=-1)], axis=-1)
