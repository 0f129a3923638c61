"""Property tests of the cone metrics (hypothesis): finite for every finite input, invariant to
scale, zero error inside the cone."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from metrics_reference import CONE_KEYS, SUMMARY_KEYS, one, pred_with_slope

from vistac_learn.metrics import cone_metrics, per_sample_metrics

PROPERTY_SETTINGS = settings(
    max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow]
)


# --------------------------------------------------------------------------------------------
# Properties (hypothesis)
# --------------------------------------------------------------------------------------------

SPECIAL = [0.0, -0.0, 5e-324, -5e-324, 1e-320, 1e-300, -1e-300, 1e-8, -1e-8, 1.0, -1.0,
           1e300, -1e300, 1.7e308, -1.7e308]  # fmt: skip
component = st.one_of(
    st.sampled_from(SPECIAL), st.floats(allow_nan=False, allow_infinity=False, width=64)
)
vector = st.tuples(component, component)
pressing_angle = st.floats(-1.5, 1.5)  # radians from the normal, labels press into the pad


@st.composite
def label_set(draw, allow_odd=True):
    """1-5 labels: unit vectors at random angles, all identical, or (with allow_odd) any."""
    kind = draw(st.sampled_from(["unit", "identical", "odd"] if allow_odd else ["unit", "same"]))
    k = draw(st.integers(1, 5))
    if kind == "odd":
        return np.array(draw(st.lists(vector, min_size=1, max_size=5)), dtype=float)
    if kind == "identical" or kind == "same":
        a = draw(pressing_angle)
        return np.tile([math.sin(a), -math.cos(a)], (k, 1))
    a = np.array(draw(st.lists(pressing_angle, min_size=k, max_size=k)))
    return np.stack([np.sin(a), -np.cos(a)], axis=1)


@st.composite
def case(draw, pred_vectors=vector, allow_odd=True):
    sets = draw(st.lists(label_set(allow_odd=allow_odd), min_size=1, max_size=4))
    preds = draw(st.lists(pred_vectors, min_size=1, max_size=12))
    cone_of = draw(st.lists(st.integers(0, len(sets) - 1), min_size=len(preds),
                            max_size=len(preds)))  # fmt: skip
    return np.array(preds, dtype=float), np.array(cone_of), sets


def assert_all_finite(result):
    for key in SUMMARY_KEYS:
        assert math.isfinite(result[key]), key
    for key, values in result["per_sample"].items():
        assert np.isfinite(values.astype(float)).all(), key
    ps = result["per_sample"]
    assert (ps["error_pct"] >= 0).all() and (ps["inacc_edge_pct"] >= 0).all()
    assert (ps["angle_to_cone_deg"] <= 180).all() and (ps["angle_to_mean_deg"] <= 180).all()


@PROPERTY_SETTINGS
@given(case())
def test_finite_for_any_finite_input(args):
    with np.errstate(over="raise", invalid="raise", divide="raise", under="ignore"):
        result = cone_metrics(*args)
    assert_all_finite(result)


@PROPERTY_SETTINGS
@given(case(pred_vectors=st.tuples(st.sampled_from(SPECIAL[:9]), component)))
def test_finite_for_y_at_or_near_zero(args):
    assert_all_finite(cone_metrics(*args))


@PROPERTY_SETTINGS
@given(case(pred_vectors=st.tuples(component, st.sampled_from(SPECIAL[:9]))))
def test_finite_for_z_at_or_near_zero(args):
    assert_all_finite(cone_metrics(*args))


magnitude = st.one_of(st.just(0.0), st.floats(1e-100, 1e100), st.floats(-1e100, -1e-100))


@PROPERTY_SETTINGS
@given(case(pred_vectors=st.tuples(magnitude, magnitude)), st.integers(-200, 200))
def test_cone_metrics_are_exactly_invariant_to_power_of_two_scaling(args, k):
    preds, cone_of, sets = args
    base = per_sample_metrics(preds, cone_of, sets)
    scaled = per_sample_metrics(preds * 2.0**k, cone_of, sets)
    for key in CONE_KEYS:
        np.testing.assert_array_equal(scaled[key], base[key], err_msg=key)


@PROPERTY_SETTINGS
@given(
    case(pred_vectors=st.tuples(st.floats(-10, 10), st.floats(-10, -1e-3)), allow_odd=False),
    st.floats(1e-6, 1e6),
)
def test_cone_metrics_are_invariant_to_positive_scaling(args, factor):
    preds, cone_of, sets = args
    base = cone_metrics(preds, cone_of, sets)
    scaled = cone_metrics(preds * factor, cone_of, sets)
    for key in CONE_KEYS:
        a, b = scaled["per_sample"][key], base["per_sample"][key]
        if a.dtype == bool:
            np.testing.assert_array_equal(a, b, err_msg=key)
        else:  # slopes differ by a few ulp; inacc divides their difference by w >= EPS_W
            np.testing.assert_allclose(a, b, rtol=1e-8, atol=1e-6, err_msg=key)
    for key in SUMMARY_KEYS:
        if key != "mse_mean":
            assert scaled[key] == pytest.approx(base[key], rel=1e-8, abs=1e-6), key


@PROPERTY_SETTINGS
@given(
    st.lists(pressing_angle, min_size=1, max_size=6),
    st.floats(0.0, 1.0),
    st.floats(1e-100, 1e100),
)
def test_in_cone_predictions_score_zero_error(angles, t, scale):
    labels = np.stack([np.sin(angles), -np.cos(angles)], axis=1)
    m = labels[:, 0] / labels[:, 1]
    inside = m.min() + t * (m.max() - m.min())
    r = one(pred_with_slope(inside, scale), labels)
    assert r["in_cone"]
    assert r["error_pct"] == r["inacc_edge_pct"] == r["angle_to_cone_deg"] == 0.0
