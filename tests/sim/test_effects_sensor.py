"""FTS-3 sensor model: each part shows its signature on a force series (T, 2, 3)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from vistac.errors import UserError
from vistac_sim.effects.fts3 import (
    BiasDrift,
    Fts3Cfg,
    Hysteresis,
    NonLinearity,
    Quantisation,
    SampleNoise,
    Saturation,
    ZeroOffset,
    fts3_effects,
    hysteresis_state,
)
from vistac_sim.effects.registry import Pipeline
from vistac_sim.recording.config import RecordingCfg
from vistac_sim.recording.session import press_envelopes, simulate_session

DT = 0.02


def _ramp(peak: float, n: int = 401) -> np.ndarray:
    """(2n - 1, 2, 3) series: every channel rises linearly 0 -> peak, then falls back to 0."""
    up = np.linspace(0.0, peak, n)
    x = np.r_[up, up[-2::-1]]
    return np.broadcast_to(x[:, None, None], (len(x), 2, 3)).copy()


def _reference_state(x: np.ndarray, smoothing: float) -> np.ndarray:
    """Plain per-sample loop of the Duhem recurrence (the obvious, slow version)."""
    s = np.zeros_like(x)
    state = np.zeros(x.shape[1])
    direction = np.zeros(x.shape[1])
    for t in range(len(x)):
        step = x[t] - x[t - 1] if t else np.zeros(x.shape[1])
        direction = np.where(step != 0, np.sign(step), direction)
        state = direction + (state - direction) * np.exp(-np.abs(step) / smoothing)
        s[t] = state
    return s


@settings(max_examples=40, deadline=None)
@given(arrays(np.float64, (60, 3), elements=st.floats(-10, 10)), st.floats(0.01, 2.0))
def test_hysteresis_state_matches_per_sample_loop(x, smoothing):
    x[5:9] = x[4]  # a stretch without change keeps the state
    np.testing.assert_allclose(hysteresis_state(x, smoothing), _reference_state(x, smoothing),
                               atol=1e-12)


@pytest.mark.parametrize("width", [0.02, 0.05])
def test_hysteresis_loading_and_unloading_differ_by_width(width):
    full_scale = 10.0
    x = _ramp(full_scale)
    y = Hysteresis(width=width, smoothing=0.05)(x, DT, None)
    n = (len(x) + 1) // 2
    load, unload = y[:n, 0, 2], y[n - 1:, 0, 2][::-1]  # both indexed by the same input
    gap = unload - load
    inp = x[:n, 0, 2]
    mid = (inp > 1.0) & (inp < 9.0)  # away from the turning points
    np.testing.assert_allclose(gap[mid], width * inp[mid], rtol=1e-6)
    # datasheet: the widest gap of a full-scale cycle is `width` of full scale (a little less
    # near the turning point, where the branch switch is smoothed over ~0.05 N)
    assert 0.95 * width * full_scale < gap.max() <= width * full_scale
    assert abs(y[0, 0, 2]) < 1e-12 and abs(y[-1, 0, 2]) < 1e-12  # the loop closes at zero
    assert np.all(load <= inp + 1e-12) and np.all(unload[mid] > inp[mid])  # the reading lags


def test_hysteresis_of_a_negative_press_lags_in_magnitude():
    x = -_ramp(2.0)
    y = Hysteresis(width=0.02)(x, DT, None)
    n = (len(x) + 1) // 2
    assert abs(y[n - 1, 0, 2]) < abs(x[n - 1, 0, 2])  # at the peak, below the input
    assert np.all(np.abs(y[n + 20:-1, 0, 2]) > np.abs(x[n + 20:-1, 0, 2]))  # unloading above


def test_nonlinearity_bows_by_the_configured_fraction_of_full_scale():
    x = np.linspace(-10, 10, 2001)[:, None, None] * np.ones((1, 2, 3))
    y = NonLinearity(fraction=0.025, full_scale=10.0)(x, DT, None)
    dev = y - x
    assert np.abs(dev).max() == pytest.approx(0.25, rel=1e-9)
    assert dev[np.argmin(np.abs(x[:, 0, 0] - 5.0)), 0, 0] == pytest.approx(0.25)
    assert dev[np.argmin(np.abs(x[:, 0, 0] + 5.0)), 0, 0] == pytest.approx(-0.25)
    assert np.all(np.abs(dev[[0, 1000, -1]]) < 1e-12)  # exact at 0 and at full scale
    assert np.all(np.diff(y[:, 0, 0]) > 0)  # monotone: a peak stays a peak


def test_quantisation_puts_readings_on_the_1_mN_grid():
    rng = np.random.default_rng(0)
    y = Quantisation(step=0.001)(rng.uniform(-3, 3, (500, 2, 3)), DT, None)
    mn = y * 1000.0
    np.testing.assert_allclose(mn, np.round(mn), atol=1e-9)


def test_saturation_at_10_N():
    x = _ramp(14.0)
    y = Saturation(full_scale=10.0)(x, DT, None)
    assert y.max() == 10.0
    np.testing.assert_array_equal(y[x <= 10.0], x[x <= 10.0])
    assert Saturation(full_scale=10.0)(-x, DT, None).min() == -10.0


def test_zero_offset_is_constant_per_session_and_differs_between_sessions():
    x = _ramp(2.0)
    eff = ZeroOffset(std=0.01)
    d1 = eff(x, DT, np.random.default_rng(1)) - x
    d2 = eff(x, DT, np.random.default_rng(2)) - x
    np.testing.assert_allclose(d1, np.broadcast_to(d1[0], d1.shape), atol=1e-15)
    assert not np.allclose(d1[0], d2[0])
    stds = [ZeroOffset(std=0.01)(x[:1], DT, np.random.default_rng(s))[0] for s in range(400)]
    assert np.std(stds) == pytest.approx(0.01, rel=0.1)


def test_drift_is_slow_bounded_and_starts_at_zero():
    x = np.zeros((30_000, 2, 3))  # 10 minutes at 50 Hz
    std, tau = 0.02, 30.0
    d = BiasDrift(std=std, tau=tau)(x, DT, np.random.default_rng(3))
    assert np.all(d[0] == 0.0)  # tared at the start of the session
    assert np.abs(d).max() < 3 * std  # bounded by construction
    step = np.abs(np.diff(d, axis=0))
    assert step.max() < 0.2 * std  # slow: tiny changes from sample to sample
    assert 0.5 * std < d.std() < 1.2 * std  # but it does wander by about its std
    lag = int(tau / DT)
    corr = np.corrcoef(d[:-lag, 0, 0], d[lag:, 0, 0])[0, 1]
    assert 0.1 < corr < 0.7  # correlation ~ 1/e after tau


def test_sample_noise_is_white_with_the_configured_std():
    x = np.zeros((20_000, 2, 3))
    n = SampleNoise(std=0.003)(x, DT, np.random.default_rng(4))
    assert n.std() == pytest.approx(0.003, rel=0.02)
    assert abs(np.corrcoef(n[:-1, 0, 0], n[1:, 0, 0])[0, 1]) < 0.03


def test_fts3_builds_only_non_zero_parts_in_signal_chain_order():
    names = [e.name for e in fts3_effects(Fts3Cfg())]
    assert names == ["fts3.hysteresis", "fts3.nonlinearity", "fts3.zero_offset", "fts3.drift",
                     "fts3.sample_noise", "fts3.saturation", "fts3.quantisation"]
    off = Fts3Cfg(nonlinearity=0, hysteresis=0, drift_std=0, offset_std=0, sample_noise=0)
    assert [e.name for e in fts3_effects(off)] == ["fts3.saturation", "fts3.quantisation"]
    with pytest.raises(UserError, match="hysteresis: must be >= 0"):
        Fts3Cfg(hysteresis=-0.1)
    with pytest.raises(UserError, match="monotone"):
        Fts3Cfg(nonlinearity=0.3)
    with pytest.raises(UserError, match="nonlinearity: needs a positive full_scale"):
        Fts3Cfg(full_scale=0.0)
    with pytest.raises(UserError, match="drift_tau: must be > 0"):
        Fts3Cfg(drift_tau=0)


def test_session_presses_peak_at_the_solved_force_and_rest_is_zero():
    cfg = RecordingCfg()
    forces = np.random.default_rng(5).normal(0, 0.3, (6, 2, 3))
    forces[..., 2] = -2.0
    s = simulate_session(forces, Pipeline(), cfg, np.random.default_rng(6), None)
    np.testing.assert_array_equal(s.readings, forces)  # bitwise: no effect, no change
    env = s.envelope
    assert env.max() == 1.0 and np.all(env >= 0)
    assert np.all(env[s.press < 0] == 0) and np.all(s.press[env > 0] >= 0)  # rest is rest
    assert np.all(np.diff(s.press[s.press >= 0]) >= 0)  # presses in order, never overlapping
    # each press: strictly rising up to the peak, falling right after it
    for p in s.peaks:
        assert env[p - 1] < env[p] and env[p + 1] < env[p]
    gaps = np.diff(np.flatnonzero(np.diff((env > 0.2).astype(int)) != 0))[1::2]
    assert gaps.min() >= 0.8 * cfg.rest_s * cfg.rate_hz  # clear rest between presses
    _, _, peaks = press_envelopes(6, cfg, np.random.default_rng(6))
    np.testing.assert_array_equal(peaks, s.peaks)  # the timing is its own stream


def test_full_sensor_model_keeps_rest_low_and_readings_close_to_the_press():
    forces = np.zeros((6, 2, 3))
    forces[..., 1], forces[..., 2] = 0.4, -2.0
    pipe = Pipeline(sensor=fts3_effects(Fts3Cfg()))
    s = simulate_session(forces, pipe, RecordingCfg(), np.random.default_rng(7),
                         np.random.default_rng(8))
    rest = s.envelope == 0
    assert np.abs(s.measured[rest]).max() < 0.1  # offset + drift + noise, far below 0.5 N
    np.testing.assert_allclose(s.readings, forces, atol=0.2)  # bow + lag + bias: < 10 %
    assert not np.allclose(s.readings[0], s.readings[1], atol=1e-4)  # presses differ


def test_session_memory_is_linear_in_the_presses():
    """`--repeats` K: a session's memory grows like K (the series), not K^2 (issue 22: a (T, K)
    table of envelopes took 9.4 GiB at K = 3000)."""
    import tracemalloc

    pipe = Pipeline(sensor=fts3_effects(Fts3Cfg()))

    def peak(k: int) -> tuple[int, int]:
        forces = np.zeros((k, 2, 3))
        forces[..., 2] = -2.0
        tracemalloc.start()
        s = simulate_session(forces, pipe, RecordingCfg(), np.random.default_rng(1),
                             np.random.default_rng(2))
        size = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        return size, len(s.true)

    (small, _), (large, samples) = peak(40), peak(400)
    assert large < 16 * small  # 10x the presses: about 10x the memory (K^2 would be 100x)
    assert large < 40 * samples * 6 * 8  # a few dozen (T, 2, 3) float arrays at most
