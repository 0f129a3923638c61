"""Friction is physics: Coulomb's prediction on flat faces, the grasp sampler's push angles, the
cone bound on drawn grasps, and determinism of the two-phase press."""

import numpy as np
import pytest
from hard_cases import KNOWN_REASONS

from vistac.config import apply
from vistac_sim.generate.config import GenerateCfg
from vistac_sim.generate.rigs import ObjectRig, solve
from vistac_sim.geometry import angle_deg
from vistac_sim.objects.library import build_object, procedural_library
from vistac_sim.physics.analytic import FACES, analytic_press, face_grasp, face_object
from vistac_sim.physics.checks import RejectedSample

FRICTIONS = (0.0, 0.3, 0.5, 0.8, 1.0)
PUSH_DEG = (0.0, 10.0, 20.0, 30.0, 45.0)


@pytest.mark.parametrize("face", FACES)
@pytest.mark.parametrize("friction", FRICTIONS)
def test_force_angle_is_min_of_push_angle_and_atan_mu(face, friction):
    """Stick: the force follows the push; slip: it lies on the cone's edge (within 1 deg)."""
    for push in PUSH_DEG:
        r = analytic_press(face, push, friction)
        assert abs(r.error_deg) <= 1.0, (face, friction, push, r.measured_deg, r.expected_deg)


def test_friction_changes_the_label():
    """The same 30 deg push: frictionless along the normal, mu 0.3 on the cone edge, mu 0.8
    along the push (the knob is not a no-op)."""
    angles = [analytic_press("wall", 30.0, mu).measured_deg for mu in (0.0, 0.3, 0.8)]
    np.testing.assert_allclose(angles, [0.0, np.degrees(np.arctan(0.3)), 30.0], atol=1.0)


def test_two_phase_press_is_deterministic_and_clean():
    """Same grasp, same labels to the bit, whatever was pressed before; no MuJoCo warning."""
    cfg = GenerateCfg()
    scene = ObjectRig(face_object("wall", 30.0, cfg.hand.height), cfg, render=False)
    a = scene.press.run(face_grasp("wall", 30.0, cfg.hand.tip_radius)).force_sensor
    scene.press.run(face_grasp("wall", 10.0, cfg.hand.tip_radius))
    b = scene.press.run(face_grasp("wall", 30.0, cfg.hand.tip_radius)).force_sensor
    assert np.array_equal(a, b)
    d = scene.press.data
    assert not d.warning.number.any()
    assert np.isfinite(d.qpos).all() and np.isfinite(d.qvel).all() and np.isfinite(a).all()


def _drawn(cfg: GenerateCfg, per_family: int = 3, seed: int = 0):
    """Accepted presses drawn as `vistac generate` draws them, a few per procedural family."""
    out = []
    for spec in procedural_library(cfg.objects, seed)[:len(cfg.objects.families)]:
        scene = ObjectRig(build_object(spec, cfg.hand.height), cfg, render=False)
        rng, done = np.random.default_rng(seed), 0
        for _ in range(40):
            try:
                grasp = scene.sampler.sample(rng)
                res, normal = solve(scene, grasp, cfg)
            except RejectedSample as exc:
                assert exc.reason in KNOWN_REASONS
                continue
            out.append((grasp, res, normal))
            done += 1
            if done == per_family:
                break
    return out


def test_hand_closes_along_its_own_direction():
    """Both fingers push along one axis, so the thumb's push is off its surface normal wherever
    the shape says, not drawn around it; each finger's own axis (its sensor frame) is drawn
    around its normal."""
    cfg = GenerateCfg()
    drawn = _drawn(cfg)
    push_to_normal, axis_to_normal = [], []
    for grasp, _, _ in drawn:
        np.testing.assert_allclose(grasp.push[1], -grasp.push[0], atol=1e-12)
        push_to_normal.append(angle_deg(grasp.push, -grasp.normal))
        axis_to_normal.append(angle_deg(grasp.approach, -grasp.normal))
    push_to_normal = np.concatenate(push_to_normal)
    assert push_to_normal.max() <= cfg.grasp.max_push_angle_deg + 1e-9
    assert np.median(push_to_normal) >= 3.0
    assert np.max(axis_to_normal) <= cfg.grasp.approach_spread_deg + 1e-9


def test_labels_spread_inside_the_cone_at_mu_08():
    """With friction 0.8 the force leaves the normal by a few degrees (median) and never by more
    than atan(0.8) + 2 deg."""
    cfg = apply(GenerateCfg(), {"physics": {"friction": 0.8}})
    drawn = _drawn(cfg)
    ang = np.concatenate([angle_deg(res.force_sensor, normal) for _, res, normal in drawn])
    assert np.median(ang) >= 3.0
    assert ang.max() <= np.degrees(np.arctan(0.8)) + 2.0
    # Labels are informative: the force is not simply along each pad's z.
    r_y = np.concatenate([res.force_sensor[:, 1] / np.linalg.norm(res.force_sensor[:, 1:], axis=1)
                          for _, res, _ in drawn])
    assert np.median(np.abs(r_y)) >= 0.05


def test_the_cone_check_rejects_exactly_the_forces_beyond_the_cone():
    """`check_physics` compares cosines; it must agree with the angle to the normal everywhere
    but a hair's breadth from the cone's edge (and pass a zero force, as the angle does)."""
    from vistac_sim.physics.checks import check_physics

    rng = np.random.default_rng(7)
    friction, tol = 0.8, 0.5
    limit = np.degrees(np.arctan(friction)) + tol
    decided = 0
    for _ in range(2000):
        normal = rng.normal(size=(2, 3))
        force = normal + rng.normal(scale=rng.uniform(0.05, 2.0), size=(2, 3))
        force[:, 2] = -np.abs(force[:, 2]) - 1e-3  # pushing: the pulling check passes
        normal[:, 2] = -np.abs(normal[:, 2])
        ang = angle_deg(force, normal)
        if np.any(np.abs(ang - limit) < 1e-6):
            continue
        decided += 1
        beyond = bool(np.any(ang > limit))
        try:
            check_physics(force, normal, friction, tol)
            rejected = False
        except RejectedSample as exc:
            assert exc.reason == "outside_friction_cone"
            rejected = True
        assert rejected == beyond, (force, normal, ang)
    assert decided > 1900
    check_physics(np.array([[0.0, 0.0, -1.0], [0.0, 0.0, -1.0]]), np.zeros((2, 3)), 0.0, 0.0)


@pytest.mark.parametrize("friction", (0.0, 0.2))
def test_grasps_are_antipodal_within_a_narrow_cone(friction):
    """Where the friction cone (plus the check's tolerance) is narrower than the closing spread,
    both pushes lie within it of their surface normals, and every family still gives its
    presses (issue 22: at friction 0 draws that slide used to exhaust the redraws)."""
    from vistac_sim.generate.grasps import cone_limit_deg

    cfg = apply(GenerateCfg(), {"physics": {"friction": friction}})
    limit = cone_limit_deg(friction, cfg.physics.cone_tolerance_deg)
    assert limit < cfg.grasp.closing_spread_deg
    drawn = _drawn(cfg)
    assert len(drawn) == 3 * len(cfg.objects.families)
    for grasp, _, _ in drawn:
        assert angle_deg(grasp.push, -grasp.normal).max() <= limit + 1e-9


def test_the_default_friction_draws_as_before():
    """At the default friction the cone is wider than the closing spread: no antipodal search,
    the draws (and the datasets' bytes) are those of the sampler without it."""
    from vistac_sim.generate.grasps import OutlineSampler

    cfg = GenerateCfg()
    spec = procedural_library(cfg.objects, 0)[0]
    obj = build_object(spec, cfg.hand.height)
    assert OutlineSampler.of(obj, cfg).antipodal_deg is None
    cfg = apply(cfg, {"physics": {"friction": 0.0}})
    assert OutlineSampler.of(obj, cfg).antipodal_deg == cfg.physics.cone_tolerance_deg
