"""The simulated recording session of one configuration: K presses as a 50 Hz force series.

The operator presses K times in a row: rest, then per press a rise (smooth start, a sharp peak
at the solved force), a relaxation of `overshoot` towards the hold level, the hold, a release
to zero and rest again. Each press is its solved (K, 2, 3) force times its envelope, which is
exactly 1 at the press's peak sample and 0 outside the press.

The sensor effects run along the series (`Pipeline.apply_sensor`), and a press's reading is the
measured series at its peak sample. So `presses.parquet` and the recording CSV agree by
construction, and the study's preprocessing (threshold split on |index F_z|, first extremum
beyond the segment mean) finds that same sample: the rise is monotone and the force falls
right after the peak.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from vistac_sim.recording.config import RecordingCfg

if TYPE_CHECKING:
    from vistac_sim.effects.registry import Pipeline


@dataclass
class Session:
    """A simulated session: envelopes, peak samples, true and measured force series."""

    dt: float  # s per sample
    weights: np.ndarray  # (T, K) envelope of each press (0 outside it, 1 at its peak)
    peaks: np.ndarray  # (K,) sample index of each press's peak
    true: np.ndarray  # (T, 2, 3) force on the pads, N, sensor frame
    measured: np.ndarray  # (T, 2, 3) after the sensor effects

    @property
    def readings(self) -> np.ndarray:
        """(K, 2, 3) per-press readings: the measured series at each peak."""
        return self.measured[self.peaks]

    @property
    def envelope(self) -> np.ndarray:
        """(T,) envelope of the whole session (presses do not overlap)."""
        return self.weights.sum(axis=1)


def press_envelopes(k: int, cfg: RecordingCfg, rng: np.random.Generator
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Envelopes of K presses in a row and their peak samples.

    Args:
        k: number of presses.
        cfg: durations (s), rate, overshoot and timing jitter.
        rng: draws the per-press durations.

    Returns:
        (T, K) weights (each column one press: 0 outside, exactly 1 at its peak) and (K,) peaks.
    """
    rate = cfg.rate_hz
    jitter = rng.uniform(1 - cfg.timing_jitter, 1 + cfg.timing_jitter, (k, 4))
    base = np.array([cfg.rise_s, cfg.hold_s, cfg.release_s, cfg.rest_s]) * rate
    counts = np.maximum(np.round(base * jitter), 2).astype(int)
    lead = max(int(round(cfg.rest_s * rate)), 2)
    total = lead + int(counts.sum())
    weights = np.zeros((total, k))
    peaks = np.zeros(k, dtype=int)
    start = lead
    for p, (n_rise, n_hold, n_rel, n_rest) in enumerate(counts):
        rise = 1.0 - np.cos(0.5 * np.pi * np.arange(1, n_rise + 1) / n_rise)
        rise[-1] = 1.0  # the peak: exactly the solved force
        hold = 1.0 - cfg.overshoot * (1.0 - np.exp(-np.arange(1, n_hold + 1)
                                                   / (cfg.relax_s * rate)))
        release = hold[-1] * 0.5 * (1.0 + np.cos(np.pi * np.arange(1, n_rel + 1) / n_rel))
        env = np.r_[rise, hold, release]
        weights[start:start + len(env), p] = env
        peaks[p] = start + n_rise - 1
        start += len(env) + n_rest
    return weights, peaks


def simulate_session(forces: np.ndarray, pipeline: Pipeline, cfg: RecordingCfg,
                     profile_rng: np.random.Generator, sensor_rng: np.random.Generator
                     ) -> Session:
    """Run the K presses of a configuration as a force series through the sensor effects.

    Args:
        forces: (K, 2, 3) solved force of each press (after the force-stage effects), N.
        pipeline: its ``sensor`` effects run along the series.
        cfg: the session's timing.
        profile_rng: draws the press timing.
        sensor_rng: handed to the sensor effects.

    Returns:
        The session; ``session.readings`` are the per-press readings.
    """
    k = len(forces)
    weights, peaks = press_envelopes(k, cfg, profile_rng)
    true = (weights @ forces.reshape(k, -1)).reshape(len(weights), *forces.shape[1:])
    dt = 1.0 / cfg.rate_hz
    measured = pipeline.apply_sensor(true, dt, sensor_rng)
    return Session(dt, weights, peaks, true, measured)
