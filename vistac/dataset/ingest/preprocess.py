"""The study's tactile preprocessing, automatic: grasps, representative samples, rejections.

See `vistac.dataset.ingest` for the steps and the rejection criteria (`REASONS`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vistac.dataset import FINGERS
from vistac.dataset.ingest.config import IngestCfg

REASONS = ("too_short", "truncated", "saturated", "no_extremum", "below_resolution", "pulling")


def split_grasps(fz_index: np.ndarray, threshold: float) -> np.ndarray:
    """(S, 2) [start, end) sample ranges where |index F_z| > threshold, in time order."""
    above = np.abs(np.asarray(fz_index, float)) > threshold
    edges = np.diff(np.r_[0, above.astype(np.int8), 0])
    return np.stack([np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)], axis=1)


def representative_sample(fz: np.ndarray) -> int | None:
    """Index into `fz` of its first local extremum beyond its mean, or None.

    A trough (value below the mean) when the mean is negative, a peak when it is positive; a run
    of equal values counts as one value and yields its first index; the first and last runs
    are never extrema.
    """
    fz = np.asarray(fz, float)
    mean = fz.mean()
    x = fz if mean >= 0 else -fz  # look for peaks of x above |mean|
    starts = np.r_[0, np.flatnonzero(np.diff(x) != 0) + 1]
    v = x[starts]
    inner = v[1:-1]
    hits = np.flatnonzero((inner > v[:-2]) & (inner > v[2:]) & (inner > abs(mean)))
    return int(starts[hits[0] + 1]) if len(hits) else None


@dataclass
class RecordedGrasp:
    """One segment of a recording and what became of it."""

    repeat: int
    start: int  # first sample (0-based data row)
    end: int  # one past the last sample
    sample: int | None = None  # representative sample (data row), if found
    reason: str | None = None  # None: kept
    detail: str = ""


def preprocess(forces: np.ndarray, cfg: IngestCfg) -> list[RecordedGrasp]:
    """Split one recording into grasps, pick each one's sample and apply the criteria.

    Args:
        forces: (T, 2, 3) series in N: sample, finger (index, thumb), sensor-frame xyz.
        cfg: thresholds and criteria.

    Returns:
        Every segment as a `RecordedGrasp`, `reason` None for the kept ones.
    """
    n = len(forces)
    out = []
    for k, (a, b) in enumerate(split_grasps(forces[:, 0, 2], cfg.threshold)):
        g = RecordedGrasp(k, int(a), int(b))
        out.append(g)
        if b - a < cfg.min_samples:
            g.reason, g.detail = "too_short", f"{b - a} samples < {cfg.min_samples}"
            continue
        if a == 0 or b == n:
            g.reason = "truncated"
            g.detail = "starts with the recording" if a == 0 else "ends with the recording"
            continue
        seg = forces[a:b]
        peak = np.abs(seg).max(axis=0)
        if (peak >= cfg.saturation).any():
            f, c = np.argwhere(peak >= cfg.saturation)[0]
            g.reason = "saturated"
            g.detail = f"{FINGERS[f]} F_{'xyz'[c]} reached {peak[f, c]:.3f} N"
            continue
        i = representative_sample(seg[:, 0, 2])
        if i is None:
            g.reason, g.detail = "no_extremum", "index F_z has no extremum beyond its mean"
            continue
        g.sample = a + i
        yz = np.linalg.norm(forces[g.sample, :, 1:], axis=-1)
        if (yz < cfg.min_force).any():
            f = int(np.argmax(yz < cfg.min_force))
            g.reason = "below_resolution"
            g.detail = f"{FINGERS[f]} |F_yz| = {yz[f]:.4f} N < {cfg.min_force} N"
            continue
        fz = forces[g.sample, :, 2]
        if not cfg.allow_pulling and (fz >= 0).any():
            f = int(np.argmax(fz >= 0))
            g.reason, g.detail = "pulling", f"{FINGERS[f]} F_z = {fz[f]:.4f} N >= 0"
    return out
