"""FTS-3 fingertip sensor model: effects that turn a true force series into sensor readings.

Every part is a ``sensor``-stage effect, ``effect(series, dt, rng) -> series`` on the force series
of one recording session, shape (T, 2, 3): 50 Hz sample, finger (index, thumb), sensor-frame xyz,
newtons. They run in the order of the signal chain:

1. `Hysteresis` (the pad's elastomer lags its load): history dependent, per axis.
2. `NonLinearity` (the transducer's static curve): a bow of at most ``nonlinearity * full_scale``.
3. `ZeroOffset` (what calibration left): one constant per axis and session.
4. `BiasDrift` (slow drift within a session): a bounded, slow random process starting at 0.
5. `SampleNoise` (electronics): white noise per sample.
6. `Saturation` (range): clipped to +-full_scale per axis.
7. `Quantisation` (resolution): rounded to the 1 mN grid.

`fts3_effects(cfg)` builds the parts whose parameter is non-zero; a zero part is never built.
The model's parameters (`Fts3Cfg`) default to the sensor's datasheet values.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from vistac.config import Config, ConfigError, param
from vistac_sim.effects.registry import Effect, register_effect


@dataclass(frozen=True)
class Fts3Cfg(Config):
    """FTS-3 fingertip sensor model, applied along the 50 Hz force series (per axis, newtons).

    Defaults are the datasheet values of the thesis (range 10 N, resolution 1 mN, non-linearity
    2.5 %, hysteresis 2 %); drift, offset and sample noise are not on the datasheet and are our
    estimates. A part whose parameter is 0 is not built.
    """

    full_scale: float = param(10.0, ge=0, help="N per axis; readings saturate at +-full_scale "
                              "(0: no saturation)")
    resolution: float = param(0.001, ge=0, help="N, quantisation step of the readings (0: off)")
    nonlinearity: float = param(0.025, ge=0, lt=0.25, why="the curve must stay monotone",
                                help="max deviation from linear, fraction of full scale (0: off)")
    hysteresis: float = param(0.02, ge=0, help="loading/unloading loop width, fraction of |input| "
                              "(0: off)")
    hysteresis_smoothing: float = param(0.05, gt=0, help="N of input travel over which a branch "
                                        "switch completes")
    drift_std: float = param(0.01, ge=0, help="N, stationary std of the slow bias drift (0: off)")
    drift_tau: float = param(30.0, gt=0, help="s, correlation time of the drift")
    offset_std: float = param(0.005, ge=0, help="N, std of the zero offset left by calibration "
                              "(0: off)")
    sample_noise: float = param(0.002, ge=0, help="N, white noise std per sample (0: off)")

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.nonlinearity > 0 and self.full_scale <= 0:
            raise ConfigError("nonlinearity", "needs a positive full_scale")


def hysteresis_state(x: np.ndarray, smoothing: float) -> np.ndarray:
    """Branch state s in [-1, 1] of a Duhem-type hysteresis, per channel of x (T, C).

    s relaxes towards the direction of the input's change, +1 while it rises and -1 while it
    falls, exponentially in the input's travel: ``s_t = d + (s_{t-1} - d) exp(-|x_t - x_{t-1}|
    / smoothing)`` with d the sign of the last non-zero change; s starts at 0. Solved exactly per
    monotone run (a few runs per press), not per sample.

    Args:
        x: (T, C) input series.
        smoothing: input travel (same unit as x) over which s covers 1 - 1/e of a switch.

    Returns:
        (T, C) branch state.
    """
    n, c = x.shape
    step = np.diff(x, axis=0, prepend=x[:1])
    sign = np.sign(step)
    last = np.where(sign != 0, np.arange(n)[:, None], 0)
    np.maximum.accumulate(last, axis=0, out=last)
    direction = np.take_along_axis(sign, last, axis=0)
    travel = np.cumsum(np.abs(step), axis=0) / smoothing
    s = np.empty_like(x, dtype=float)
    for j in range(c):
        starts = np.r_[0, np.flatnonzero(np.diff(direction[:, j])) + 1]
        ends = np.r_[starts[1:], n]
        prev_s, prev_travel = 0.0, 0.0
        for a, b in zip(starts, ends, strict=True):
            d = direction[a, j]
            s[a:b, j] = d + (prev_s - d) * np.exp(prev_travel - travel[a:b, j])
            prev_s, prev_travel = s[b - 1, j], travel[b - 1, j]
    return s


@dataclass(frozen=True)
class Hysteresis(Effect):
    """The reading lags its input: loading and unloading curves differ by ``width * |input|``.

    ``y = x - width / 2 * |x| * s`` with s the branch state (`hysteresis_state`): below the input
    while it rises, above while it falls, the loop closed at zero. For a full-scale cycle the
    widest gap is ``width`` of full scale (the datasheet's "hysteresis 2 %").
    """

    name: ClassVar[str] = "fts3.hysteresis"
    stage: ClassVar[str] = "sensor"
    width: float = 0.02
    smoothing: float = 0.05

    def __call__(self, series: np.ndarray, dt: float, rng: np.random.Generator) -> np.ndarray:
        flat = series.reshape(len(series), -1)
        s = hysteresis_state(flat, self.smoothing).reshape(series.shape)
        return series - 0.5 * self.width * np.abs(series) * s


@dataclass(frozen=True)
class NonLinearity(Effect):
    """Static transfer curve ``y = x + fraction * full_scale * 4 u (1 - u) sign(x)``, u = |x|/FS.

    Zero at 0 and at full scale, largest (``fraction * full_scale``) at half scale; monotone for
    fraction < 0.25, so a force peak stays a peak.
    """

    name: ClassVar[str] = "fts3.nonlinearity"
    stage: ClassVar[str] = "sensor"
    fraction: float = 0.025
    full_scale: float = 10.0

    def __call__(self, series: np.ndarray, dt: float, rng: np.random.Generator) -> np.ndarray:
        u = np.minimum(np.abs(series) / self.full_scale, 1.0)
        return series + self.fraction * self.full_scale * 4.0 * u * (1.0 - u) * np.sign(series)


@dataclass(frozen=True)
class ZeroOffset(Effect):
    """A constant offset per axis and session (Gaussian, std `std` N): calibration's leftover."""

    name: ClassVar[str] = "fts3.zero_offset"
    stage: ClassVar[str] = "sensor"
    std: float = 0.005

    def __call__(self, series: np.ndarray, dt: float, rng: np.random.Generator) -> np.ndarray:
        return series + self.std * rng.standard_normal(series.shape[1:])


@dataclass(frozen=True)
class BiasDrift(Effect):
    """Slow bias drift: an Ornstein-Uhlenbeck process per axis, starting at 0 (tared).

    Stationary std `std` N, correlation time `tau` s; softly limited to +-3 std
    (``3 std tanh(z / 3 std)``), so it never exceeds that bound.
    """

    name: ClassVar[str] = "fts3.drift"
    stage: ClassVar[str] = "sensor"
    std: float = 0.01
    tau: float = 30.0

    def __call__(self, series: np.ndarray, dt: float, rng: np.random.Generator) -> np.ndarray:
        from scipy.signal import lfilter  # imported on use: scipy.signal costs ~0.7 s per process

        a = np.exp(-dt / self.tau)
        eps = rng.standard_normal(series.shape)
        eps[0] = 0.0
        z = lfilter([self.std * np.sqrt(1.0 - a * a)], [1.0, -a], eps, axis=0)
        bound = 3.0 * self.std
        return series + bound * np.tanh(z / bound)


@dataclass(frozen=True)
class SampleNoise(Effect):
    """White Gaussian noise of std `std` N on every sample and axis."""

    name: ClassVar[str] = "fts3.sample_noise"
    stage: ClassVar[str] = "sensor"
    std: float = 0.002

    def __call__(self, series: np.ndarray, dt: float, rng: np.random.Generator) -> np.ndarray:
        return series + self.std * rng.standard_normal(series.shape)


@dataclass(frozen=True)
class Saturation(Effect):
    """Readings clipped to the range, +-`full_scale` N per axis."""

    name: ClassVar[str] = "fts3.saturation"
    stage: ClassVar[str] = "sensor"
    full_scale: float = 10.0

    def __call__(self, series: np.ndarray, dt: float, rng: np.random.Generator) -> np.ndarray:
        return np.clip(series, -self.full_scale, self.full_scale)


@dataclass(frozen=True)
class Quantisation(Effect):
    """Readings rounded to multiples of `step` N (the 1 mN resolution)."""

    name: ClassVar[str] = "fts3.quantisation"
    stage: ClassVar[str] = "sensor"
    step: float = 0.001

    def __call__(self, series: np.ndarray, dt: float, rng: np.random.Generator) -> np.ndarray:
        return np.round(series / self.step) * self.step


def fts3_effects(cfg: Fts3Cfg) -> list[Effect]:
    """The enabled parts of the FTS-3 model, in signal-chain order."""
    parts: list[Effect] = []
    if cfg.hysteresis > 0:
        parts.append(Hysteresis(width=cfg.hysteresis, smoothing=cfg.hysteresis_smoothing))
    if cfg.nonlinearity > 0:
        parts.append(NonLinearity(fraction=cfg.nonlinearity, full_scale=cfg.full_scale))
    if cfg.offset_std > 0:
        parts.append(ZeroOffset(std=cfg.offset_std))
    if cfg.drift_std > 0:
        parts.append(BiasDrift(std=cfg.drift_std, tau=cfg.drift_tau))
    if cfg.sample_noise > 0:
        parts.append(SampleNoise(std=cfg.sample_noise))
    if cfg.full_scale > 0:
        parts.append(Saturation(full_scale=cfg.full_scale))
    if cfg.resolution > 0:
        parts.append(Quantisation(step=cfg.resolution))
    return parts


register_effect("fts3", fts3_effects, cfg=Fts3Cfg)
