"""Small vectorised geometry helpers: yaw quaternions, unit vectors, angles."""

from __future__ import annotations

import numpy as np


def yaw_quat(yaw: float) -> np.ndarray:
    """MuJoCo quaternion (w, x, y, z) of a rotation by `yaw` about world z."""
    return np.array([np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)])


def unit(v: np.ndarray, axis: int = -1) -> np.ndarray:
    """`v` scaled to unit length along `axis` (zero vectors stay zero)."""
    v = np.asarray(v)
    n = np.sqrt((v * v).sum(axis=axis, keepdims=True))  # np.linalg.norm's sum, without its checks
    if (n > 0).all():  # the common case: a plain division (the same numbers, less work)
        return v / n
    return np.divide(v, n, out=np.zeros_like(v, dtype=float), where=n > 0)


def angle_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle in degrees between vectors along the last axis (robust near 0 and 180)."""
    a, b = unit(np.asarray(a, float)), unit(np.asarray(b, float))
    cross = np.linalg.norm(np.cross(a, b), axis=-1) if a.shape[-1] == 3 else np.abs(
        a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0])
    return np.degrees(np.arctan2(cross, (a * b).sum(-1)))
