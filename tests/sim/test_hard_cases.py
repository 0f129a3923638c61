"""The hard-case suite: each named hard scene yields checked labels or a named rejection."""

import numpy as np
import pytest
from hard_cases import CASES, KNOWN_REASONS, run_case, thin_wall_u

from vistac.config import apply
from vistac_sim.generate.config import GenerateCfg

SLID_OFF = {"no_contact", "not_settled"}  # a pad sliding along the face: out of travel or moving


@pytest.mark.parametrize("friction", [0.0, 0.6])
@pytest.mark.parametrize("name", sorted(CASES))
def test_hard_cases_give_checked_labels_or_a_named_reason(name, friction):
    cfg = apply(GenerateCfg(), {"physics": {"friction": friction}})
    out = run_case(name, cfg)
    if not out.accepted:
        assert out.reason in KNOWN_REASONS
        return
    assert np.isfinite(out.labels).all() and np.isfinite(out.force).all()
    np.testing.assert_allclose(np.linalg.norm(out.labels, axis=1), 1.0)
    assert np.all(out.force[:, 2] < 0)
    limit = np.degrees(np.arctan(friction)) + cfg.physics.cone_tolerance_deg
    assert np.all(out.angle_to_normal_deg <= limit)
    assert np.all(out.penetration <= cfg.physics.max_penetration)


def test_hard_case_expectations():
    cfg = apply(GenerateCfg(), {"physics": {"friction": 0.0}})
    assert run_case("fingers_same_point", cfg).reason == "fingers_overlap"
    for name in ("sharp_convex_corner", "very_small_object", "thin_wall_1mm"):
        out = run_case(name, cfg)  # corners and tiny curved objects: the normal-cone member
        assert out.accepted and np.all(out.angle_to_normal_deg < 0.5), name
    # Pushed 85 degrees off the normal, a pad slides along the face (frictionless, or with any
    # friction below tan 85 deg) until its push slide runs out of travel: nothing to label.
    for friction in (0.0, 0.8):
        cfg = apply(cfg, {"physics": {"friction": friction}})
        assert run_case("grazing_85deg", cfg).reason in SLID_OFF


def test_thin_wall_outline_has_the_wall_it_asks_for():
    poly = thin_wall_u(0.06, 0.001)
    assert poly.area == pytest.approx(0.001 * (0.06 + 2 * 0.048 - 2 * 0.001), rel=1e-9)


@pytest.mark.parametrize("friction", [0.3, 0.8])
def test_stick_and_slip_at_the_cone_edge(friction):
    cfg = apply(GenerateCfg(), {"physics": {"friction": friction}})
    cone = np.degrees(np.arctan(friction))
    stick = run_case("stick_inside_cone_edge", cfg)
    slip = run_case("slip_past_cone_edge", cfg)
    assert stick.accepted and slip.accepted
    assert stick.angle_to_normal_deg[0] == pytest.approx(cone - 2.0, abs=1.0)  # follows the push
    assert slip.angle_to_normal_deg[0] == pytest.approx(cone, abs=1.0)  # on the cone's edge
    # The thumb pushes along its normal in both: no tangential force.
    assert np.all(np.array([stick.angle_to_normal_deg[1], slip.angle_to_normal_deg[1]]) < 0.5)


@pytest.mark.parametrize("friction", [0.0, 0.8])
def test_near_zero_normal_force_keeps_its_direction(friction):
    cfg = apply(GenerateCfg(), {"physics": {"friction": friction}})
    out = run_case("near_zero_normal_force", cfg)
    assert out.accepted and np.isfinite(out.force).all()
    assert out.force[0, 2] == pytest.approx(-0.01, rel=1e-2)  # the drive's 10 mN, along the push
    expected = min(20.0, np.degrees(np.arctan(friction)))
    assert out.angle_to_normal_deg[0] == pytest.approx(expected, abs=1.0)


def test_grazing_contact_with_friction_slips_to_the_cone_edge():
    cfg = apply(GenerateCfg(), {"physics": {"friction": 0.8}})
    out = run_case("grazing_70deg_friction", cfg)
    assert out.accepted
    assert out.angle_to_normal_deg[0] == pytest.approx(np.degrees(np.arctan(0.8)), abs=1.0)
    cfg = apply(cfg, {"physics": {"friction": 0.0}})
    assert run_case("grazing_70deg_friction", cfg).reason in SLID_OFF
