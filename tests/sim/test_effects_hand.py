"""Finger pull and placement error: their signatures, and one physics solve per repeat."""

import numpy as np
import pytest

from vistac.errors import UserError
from vistac_sim.effects.finger_pull import FingerPull, FingerPullCfg
from vistac_sim.effects.placement_error import PlacementError, PlacementErrorCfg
from vistac_sim.effects.registry import Pipeline
from vistac_sim.generate.config import GenerateCfg
from vistac_sim.generate.configuration import make_configuration
from vistac_sim.generate.rigs import RigCache
from vistac_sim.hand.grasp import Grasp
from vistac_sim.objects.library import procedural_library
from vistac_sim.physics import press


def _forces(k: int) -> np.ndarray:
    f = np.zeros((k, 2, 3))
    f[..., 0], f[..., 1], f[..., 2] = 0.1, -0.3, -2.0
    return f


def test_finger_pull_shifts_mean_y_by_the_configured_fraction_of_fz():
    pull = FingerPull(FingerPullCfg(mean=0.15, spread=0.05, config_spread=0.0))
    f = _forces(20_000)
    out = pull(f, np.random.default_rng(0))
    dy = out[..., 1] - f[..., 1]
    np.testing.assert_allclose(dy.mean(axis=0), 0.15 * 2.0, atol=0.003)  # +y, both fingers
    np.testing.assert_allclose(dy.std(axis=0), 0.05 * 2.0, rtol=0.03)
    np.testing.assert_array_equal(out[..., [0, 2]], f[..., [0, 2]])  # only y changes


def test_finger_pull_config_part_is_shared_by_the_presses_of_a_configuration():
    pull = FingerPull(FingerPullCfg(mean=0.0, spread=0.0, config_spread=0.1))
    configs = np.array([pull(_forces(6), np.random.default_rng(s))[..., 1] + 0.3
                        for s in range(2000)])
    assert np.all(np.ptp(configs, axis=1) < 1e-12)  # no spread within a configuration
    np.testing.assert_allclose(configs[:, 0].std(axis=0), 0.1 * 2.0, rtol=0.06)


def test_finger_pull_only_on_listed_fingers_and_checked():
    out = FingerPull(FingerPullCfg(mean=0.2, fingers=("index",)))(_forces(5),
                                                                  np.random.default_rng(1))
    np.testing.assert_array_equal(out[:, 1], _forces(5)[:, 1])
    assert np.all(out[:, 0, 1] != -0.3)
    with pytest.raises(UserError, match="fingers: must be one of index, thumb, got 'pinky'"):
        FingerPullCfg(fingers=("pinky",))
    with pytest.raises(UserError, match="spread: must be >= 0"):
        FingerPullCfg(spread=-1.0)


def test_placement_error_jitters_targets_and_turns_approaches():
    g = Grasp(np.zeros(2), 0.0, np.array([[0.02, 0.0], [-0.02, 0.0]]),
              np.array([[1.0, 0.0], [-1.0, 0.0]]), np.array([[-1.0, 0.0], [1.0, 0.0]]))
    eff = PlacementError(PlacementErrorCfg(position_std=0.001, angle_std_deg=3.0))
    rng = np.random.default_rng(2)
    moved = [eff(g, rng) for _ in range(4000)]
    shift = np.array([m.target - g.target for m in moved])
    np.testing.assert_allclose(shift.std(axis=0), 0.001, rtol=0.05)
    approach = np.array([m.approach for m in moved])
    np.testing.assert_allclose(np.linalg.norm(approach, axis=-1), 1.0, atol=1e-12)
    turn = np.degrees(np.arctan2(approach[:, 0, 1], approach[:, 0, 0]) - np.pi)
    turn = (turn + 180) % 360 - 180
    assert turn.std() == pytest.approx(3.0, rel=0.05)
    np.testing.assert_array_equal(moved[0].normal, g.normal)  # the object is untouched
    with pytest.raises(UserError, match="position_std: must be >= 0"):
        PlacementErrorCfg(position_std=-1.0)


@pytest.fixture(scope="module")
def scenes():
    cfg = GenerateCfg()
    specs = procedural_library(cfg.objects, 0)[:2]
    cache = RigCache(specs, cfg)
    yield cfg, cache
    cache.close()


def _count_runs(monkeypatch):
    calls = []
    original = press.Press.run

    def counting(self, grasp):
        calls.append(grasp)
        return original(self, grasp)

    monkeypatch.setattr(press.Press, "run", counting)
    return calls


def test_placement_error_reruns_the_physics_per_repeat_and_repeats_differ(scenes, monkeypatch):
    cfg, cache = scenes
    calls = _count_runs(monkeypatch)
    plain = make_configuration(3, 0, cache, cfg, Pipeline())
    n_plain = len(calls)
    calls.clear()
    effect = PlacementError(PlacementErrorCfg(position_std=0.001, angle_std_deg=3.0))
    pipe = Pipeline(grasp=[effect])
    jittered = make_configuration(3, 0, cache, cfg, pipe)
    assert len(calls) >= n_plain + cfg.repeats  # one more solve (at least) per repeat
    moved = calls[n_plain:]
    assert all(not np.array_equal(g.target, moved[0].target) for g in moved[1:])
    fy = np.array([p["force_index_y"] for p in jittered.presses])
    assert np.ptp(fy) > 1e-4  # repeats differ
    fy_plain = np.array([p["force_index_y"] for p in plain.presses])
    assert np.ptp(fy_plain) == 0.0  # without effects they share one solve
    assert jittered.row["force_clean_index_y"] == plain.row["force_clean_index_y"]
