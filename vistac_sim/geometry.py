"""Small geometry helpers: yaw quaternions, unit vectors, angles (vectorised), and the closest
point on a segment (Python floats: per contact of a press)."""

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


def closest_on_segment(p, a, b) -> list[float]:
    """Closest point to `p` on the segment a-b (3-sequences of floats)."""
    ex, ey, ez = b[0] - a[0], b[1] - a[1], b[2] - a[2]
    length2 = ex * ex + ey * ey + ez * ez
    t = 0.0
    if length2 > 0:
        along = (p[0] - a[0]) * ex + (p[1] - a[1]) * ey + (p[2] - a[2]) * ez
        t = min(max(along / length2, 0.0), 1.0)
    return [a[0] + t * ex, a[1] + t * ey, a[2] + t * ez]
