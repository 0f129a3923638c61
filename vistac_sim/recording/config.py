"""The simulated recording session's settings (and whether recordings are written)."""

from __future__ import annotations

from dataclasses import dataclass

from vistac.config import Config, param


@dataclass(frozen=True)
class RecordingCfg(Config):
    """The simulated press/hold/release session of a configuration (RH8D/FTS-3 CSV stream).

    Each press: a rise (smooth start, a sharp peak at the solved force), a relaxation of
    `overshoot` towards the hold level, the hold, a release, then rest. Durations vary by
    `timing_jitter` (relative, uniform) from press to press.
    """

    write: bool = param(False, help="write recordings/NNNNNN.csv (`--recordings`)")
    rate_hz: float = param(50.0, gt=0, le=100_000, help="samples per second")
    rest_s: float = param(1.0, ge=0, help="s before the first press and after each press")
    rise_s: float = param(0.4, gt=0, help="s of a press's rise")
    hold_s: float = param(1.0, ge=0, help="s of the hold")
    release_s: float = param(0.4, gt=0, help="s of the release")
    overshoot: float = param(0.08, ge=0, lt=1, help="fraction the force relaxes after the peak")
    relax_s: float = param(0.1, gt=0, help="time constant of that relaxation")
    timing_jitter: float = param(0.2, ge=0, lt=1,
                                 help="relative, uniform variation of the durations")
