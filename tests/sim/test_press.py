"""Press physics: every scene compiles and presses cleanly, two force readings agree, frames
are right, frictionless forces follow the mesh normal, noise-only repeats share one solve."""

import numpy as np
import pytest
from hard_cases import KNOWN_REASONS

from vistac.config import apply
from vistac.dataset.schema import redraw_counts
from vistac_sim.generate.config import GenerateCfg
from vistac_sim.generate.rigs import ObjectRig, solve
from vistac_sim.geometry import angle_deg
from vistac_sim.objects.library import build_object, procedural_library
from vistac_sim.objects.outlines import CONCAVE_FAMILIES
from vistac_sim.physics.checks import RejectedSample

# The fingertip sensor frames of docs/dataset-format.md, as axes in the fingertip body frame
# (columns x_s, y_s, z_s; body x = approach, z = up): the reference the model's sensor sites
# must match.
SENSOR_FRAMES = {
    "index": np.array([[0, 0, 1], [0, 1, 0], [-1, 0, 0]], float),  # x_s = -z, y_s = y, z_s = x
    "thumb": np.array([[0, 0, 1], [0, -1, 0], [1, 0, 0]], float),  # x_s = z, y_s = -y, z_s = x
}


def sensor_rotation(finger: str, approach_xy: np.ndarray) -> np.ndarray:
    """World-from-sensor rotation (3x3, columns = sensor axes) for a finger and approach."""
    a = np.array([approach_xy[0], approach_xy[1], 0.0])
    a /= np.linalg.norm(a)
    body = np.column_stack([a, np.cross([0.0, 0.0, 1.0], a), [0.0, 0.0, 1.0]])
    return body @ SENSOR_FRAMES[finger]



def _presses(cfg, family, n, seed=0):
    spec = next(s for s in procedural_library(cfg.objects, seed) if s.family == family)
    scene = ObjectRig(build_object(spec, cfg.hand.height), cfg, render=False)
    rng = np.random.default_rng(seed)
    done = []
    while len(done) < n:
        try:
            grasp = scene.sampler.sample(rng)
            res, normal = solve(scene, grasp, cfg)
            assert not scene.press.data.warning.number.any()
            done.append((grasp, res, normal, scene))
        except RejectedSample as exc:
            assert exc.reason in KNOWN_REASONS
    return done


@pytest.mark.parametrize("family", GenerateCfg().objects.families)
def test_every_family_presses_cleanly_and_readings_agree(family):
    cfg = GenerateCfg()
    for grasp, res, _, _ in _presses(cfg, family, 4):
        np.testing.assert_allclose(res.force_sensor, res.force_sensor_check, atol=1e-6)
        assert np.all(res.force_sensor[:, 2] < 0)
        assert np.all(res.penetration <= cfg.physics.max_penetration)
        # The drive pushes with press_force along the push direction: the force balances it.
        world = np.einsum("kij,kj->ki", res.rotation, res.force_sensor)
        along = (world[:, :2] * grasp.push_dirs).sum(1)
        np.testing.assert_allclose(along, -cfg.hand.press_force, rtol=1e-3)


@pytest.mark.parametrize("family", GenerateCfg().objects.families)
def test_frictionless_force_follows_mesh_normal(family):
    cfg = apply(GenerateCfg(), {"physics": {"friction": 0.0}})
    angles = [angle_deg(res.force_sensor, normal) for _, res, normal, _ in _presses(cfg, family, 6)]
    limit = 2.0 if family in CONCAVE_FAMILIES else 0.5
    assert np.median(angles) <= limit


def test_sensor_frames_follow_contracts():
    a = np.array([0.6, 0.8])
    for finger in ("index", "thumb"):
        r = sensor_rotation(finger, a)
        np.testing.assert_allclose(r.T @ r, np.eye(3), atol=1e-12)
        assert np.linalg.det(r) == pytest.approx(1.0)
        np.testing.assert_allclose(r[:, 2], [0.6, 0.8, 0.0])  # z along the approach
        assert r[2, 1] == pytest.approx(0.0)  # y in the table plane
    np.testing.assert_allclose(sensor_rotation("index", a)[:, 1], [-0.8, 0.6, 0.0])  # +90 deg
    np.testing.assert_allclose(sensor_rotation("thumb", a)[:, 1], [0.8, -0.6, 0.0])  # mirrored


def test_site_frames_in_the_model_match_sensor_rotation():
    cfg = GenerateCfg()
    for grasp, res, _, _ in _presses(cfg, "box", 2):
        for k, finger in enumerate(("index", "thumb")):
            np.testing.assert_allclose(res.rotation[k], sensor_rotation(finger, grasp.approach[k]),
                                       atol=1e-9)


def test_unstable_press_is_rejected_not_reset():
    cfg = apply(GenerateCfg(), {"hand": {"press_force": 1e12}})  # far beyond what can settle
    spec = procedural_library(cfg.objects, 0)[1]
    scene = ObjectRig(build_object(spec, cfg.hand.height), cfg, render=False)
    rng = np.random.default_rng(0)
    reasons = set()
    for _ in range(5):
        try:
            grasp = scene.sampler.sample(rng)
            solve(scene, grasp, cfg)
        except RejectedSample as exc:
            reasons.add(exc.reason)
    assert reasons <= KNOWN_REASONS
    assert reasons & {"mujoco_warning", "non_finite", "penetration", "not_settled"}


def test_noise_only_repeats_share_one_physics_solve(monkeypatch):
    from vistac_sim.effects.registry import build_pipeline
    from vistac_sim.generate.configuration import make_configuration
    from vistac_sim.generate.rigs import RigCache
    from vistac_sim.physics.press import Press

    cfg = apply(GenerateCfg(), {"effects": {"noise": 0.05}})
    calls = []
    run = Press.run
    monkeypatch.setattr(Press, "run", lambda self, grasp: calls.append(1) or run(self, grasp))
    scenes = RigCache(procedural_library(cfg.objects, 0)[:4], cfg)
    sampler_reasons = {"unreachable", "no_opposing_thumb", "fingers_overlap"}
    for cid in range(6):
        calls.clear()
        c = make_configuration(cid, 0, scenes, cfg, build_pipeline(cfg.effects))
        reasons = redraw_counts(c.row["redraw_reasons"])
        solved_rejects = sum(v for k, v in reasons.items() if k not in sampler_reasons)
        assert len(calls) == 1 + solved_rejects  # one solve for all six noisy repeats
        assert len({p["force_index_y"] for p in c.presses}) == cfg.repeats
    scenes.close()
