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
    """A simulated session: envelope, press of each sample, peaks, true and measured series.

    Presses never overlap, so one (T,) envelope and the press each sample belongs to describe
    them all: memory is linear in the number of presses (a (T, K) table of per-press envelopes
    would grow with its square: 10 GiB at 3000 presses).
    """

    dt: float  # s per sample
    envelope: np.ndarray  # (T,) envelope of the session (0 at rest, 1 at each press's peak)
    press: np.ndarray  # (T,) index of the press each sample belongs to, -1 at rest
    peaks: np.ndarray  # (K,) sample index of each press's peak
    true: np.ndarray  # (T, 2, 3) force on the pads, N, sensor frame
    measured: np.ndarray  # (T, 2, 3) after the sensor effects

    @property
    def readings(self) -> np.ndarray:
        """(K, 2, 3) per-press readings: the measured series at each peak."""
        return self.measured[self.peaks]


def press_envelopes(k: int, cfg: RecordingCfg, rng: np.random.Generator
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Envelopes of K presses in a row, the press of each sample and the peak samples.

    Args:
        k: number of presses.
        cfg: durations (s), rate, overshoot and timing jitter.
        rng: draws the per-press durations.

    Returns:
        (T,) envelope (0 at rest, exactly 1 at each peak), (T,) press index of each sample
        (-1 at rest) and (K,) peaks.
    """
    rate = cfg.rate_hz
    jitter = rng.uniform(1 - cfg.timing_jitter, 1 + cfg.timing_jitter, (k, 4))
    base = np.array([cfg.rise_s, cfg.hold_s, cfg.release_s, cfg.rest_s]) * rate
    counts = np.maximum(np.round(base * jitter), 2).astype(int)
    lead = max(int(round(cfg.rest_s * rate)), 2)
    total = lead + int(counts.sum())
    envelope = np.zeros(total)
    press = np.full(total, -1, dtype=np.int64)
    peaks = np.zeros(k, dtype=int)
    start = lead
    for p, (n_rise, n_hold, n_rel, n_rest) in enumerate(counts):
        rise = 1.0 - np.cos(0.5 * np.pi * np.arange(1, n_rise + 1) / n_rise)
        rise[-1] = 1.0  # the peak: exactly the solved force
        hold = 1.0 - cfg.overshoot * (1.0 - np.exp(-np.arange(1, n_hold + 1)
                                                   / (cfg.relax_s * rate)))
        release = hold[-1] * 0.5 * (1.0 + np.cos(np.pi * np.arange(1, n_rel + 1) / n_rel))
        env = np.r_[rise, hold, release]
        envelope[start:start + len(env)] = env
        press[start:start + len(env)] = p
        peaks[p] = start + n_rise - 1
        start += len(env) + n_rest
    return envelope, press, peaks


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
    envelope, press, peaks = press_envelopes(k, cfg, profile_rng)
    # each sample: its press's force times the envelope (0.0 at rest, as the product of the
    # former (T, K) envelope table with the forces gave)
    flat = np.vstack([forces.reshape(k, -1), np.zeros((1, forces[0].size))])
    true = (envelope[:, None] * flat[press]).reshape(len(envelope), *forces.shape[1:])
    dt = 1.0 / cfg.rate_hz
    measured = pipeline.apply_sensor(true, dt, sensor_rng)
    return Session(dt, envelope, press, peaks, true, measured)
