"""Directions and slopes of (y, z) vectors, with the conventions that keep every metric finite.

See `vistac_learn.metrics` for the conventions and the meaning of the constants.
"""

from __future__ import annotations

import numpy as np

EPS_Z = 1e-6
EPS_M = 1e-6
EPS_W = 1e-3
IN_CONE_RTOL = 1e-9
MSE_CLIP = 1e100


def as_array(x: object, name: str) -> np.ndarray:
    """Convert an array-like (numpy, list, torch tensor) to float64, rejecting non-finite values.

    Args:
        x: the values.
        name: argument name for error messages.

    Returns:
        A float64 array.

    Raises:
        ValueError: if any value is NaN or infinite.
    """
    if hasattr(x, "detach"):  # torch tensor, without importing torch
        x = x.detach().cpu().numpy()
    arr = np.asarray(x, dtype=np.float64)
    if not np.isfinite(arr).all():
        raise ValueError(f"{name} holds {int((~np.isfinite(arr)).sum())} non-finite values")
    return arr


def as_vectors(x: object, name: str) -> np.ndarray:
    """Convert to an (N, 2) float64 array of finite (y, z) vectors.

    Args:
        x: array-like of shape (N, 2).
        name: argument name for error messages.

    Returns:
        The (N, 2) array.

    Raises:
        ValueError: for a wrong shape or non-finite values.
    """
    arr = as_array(x, name)
    if arr.size == 0:
        return arr.reshape(0, 2)
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise ValueError(f"{name} must have shape (N, 2), got {arr.shape}")
    return arr


def directions(vectors: np.ndarray) -> np.ndarray:
    """Unit direction of each (y, z) vector; the zero vector becomes (0, -1).

    Args:
        vectors: (N, 2) finite vectors.

    Returns:
        (N, 2) unit vectors (exactly scale-invariant for power-of-two scales).
    """
    vectors = np.asarray(vectors, dtype=np.float64)
    scale = np.abs(vectors).max(axis=1, keepdims=True)
    zero = scale[:, 0] == 0
    scaled = vectors / np.where(scale == 0, 1.0, scale)
    unit = scaled / np.hypot(scaled[:, :1], scaled[:, 1:]).clip(min=1.0)
    unit[zero] = (0.0, -1.0)
    return unit


def slopes(unit: np.ndarray) -> np.ndarray:
    """Slope m = y / z of unit vectors, saturated at -sign(y) / EPS_Z where z > -EPS_Z.

    Args:
        unit: (N, 2) unit vectors from `directions`.

    Returns:
        (N,) slopes, |m| <= 1 / EPS_Z; y = 0 with z > -EPS_Z gives -1 / EPS_Z.
    """
    y, z = unit[:, 0], unit[:, 1]
    pressing = z <= -EPS_Z
    saturated = np.where(y < 0, 1.0, -1.0) / EPS_Z
    return np.where(pressing, y / np.where(pressing, z, -1.0), saturated)


def angles_deg(y: np.ndarray, minus_z: np.ndarray) -> np.ndarray:
    """Angle of a direction from the into-the-pad axis (0, -1), degrees in (-180, 180].

    Args:
        y: y components.
        minus_z: -z components.

    Returns:
        atan2(y, -z) in degrees.
    """
    return np.degrees(np.arctan2(y, minus_z))


def wrap_abs_deg(delta: np.ndarray) -> np.ndarray:
    """Absolute angular difference folded into [0, 180] degrees.

    Args:
        delta: differences in degrees.

    Returns:
        |delta| modulo 360, folded to at most 180.
    """
    folded = np.abs(np.mod(delta, 360.0))
    return np.minimum(folded, 360.0 - folded)


def segment_reduce(values: np.ndarray, lengths: np.ndarray, ufunc: np.ufunc) -> np.ndarray:
    """Reduce consecutive segments of `values` with `ufunc`; empty segments give 0.

    Args:
        values: (sum(lengths), ...) concatenated segments.
        lengths: (S,) segment lengths.
        ufunc: np.minimum, np.maximum or np.add.

    Returns:
        (S, ...) reductions.
    """
    out = np.zeros((len(lengths), *values.shape[1:]))
    nonempty = lengths > 0
    if nonempty.any():
        starts = (np.cumsum(lengths) - lengths)[nonempty]
        out[nonempty] = ufunc.reduceat(values, starts, axis=0)
    return out
