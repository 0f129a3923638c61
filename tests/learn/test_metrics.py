"""Tests of the cone metrics: against a slow reference (`metrics_reference.py`) and
hand-computed cases."""

from __future__ import annotations

import math

import numpy as np
import pytest
from metrics_reference import (
    CONE,
    SUMMARY_KEYS,
    assert_close_to_reference,
    label,
    one,
    pred_with_slope,
    random_case,
)

from vistac_learn import metrics
from vistac_learn.metrics import EPS_M, EPS_W, EPS_Z, cone_metrics, summarize

# --------------------------------------------------------------------------------------------
# Against the reference
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("seed", range(4))
def test_matches_reference_on_random_cases(seed):
    assert_close_to_reference(*random_case(seed))


def test_matches_reference_on_hand_made_cases():
    label_sets = [
        [label(0.1), label(0.2), label(0.3)],
        [label(-0.5)],
        [label(0.0), label(0.0)],
        [label(-0.2), label(0.4), label(-0.2), label(1.0)],
    ]
    preds = [pred_with_slope(m) for m in (0.5, -0.1, 0.2, 0.3, -0.5, 0.01, 0.0, 2.0)]
    preds += [(0.0, 0.0), (0.0, 1.0), (1.0, 0.0), (-3.0, 0.5)]
    cone_of = [0, 0, 0, 0, 1, 2, 2, 3, 0, 1, 2, 3]
    assert_close_to_reference(np.array(preds), np.array(cone_of), label_sets)


# --------------------------------------------------------------------------------------------
# Hand-computed examples, one per metric
# --------------------------------------------------------------------------------------------

def test_the_conventions_state_the_constants_the_code_uses():
    """The module's documentation gives each constant's value; it must be the code's."""
    import re

    doc = metrics.__doc__
    for name in ("EPS_Z", "EPS_M", "EPS_W", "MSE_CLIP"):
        stated = re.search(rf"{name} = ([0-9.e+-]+)", doc)
        assert stated and float(stated.group(1)) == getattr(metrics, name), name
    assert f"|m| <= 1 / EPS_Z = {1 / EPS_Z:.0e}".replace("+0", "") in doc


def test_in_cone_tolerance_and_mse_clip_behave_as_documented():
    hi = CONE[-1][0] / CONE[-1][1]  # the cone's upper edge (slope 0.3)
    assert one(pred_with_slope(hi * (1 + 1e-12)))["in_cone"]  # rounding beyond the edge
    beyond = one(pred_with_slope(hi * (1 + 1e-6)))
    assert not beyond["in_cone"] and beyond["error_pct"] > 0
    assert metrics.IN_CONE_RTOL * max(1.0, hi) < hi * 1e-6  # the tolerance lies in between
    huge = one((1e300, -1e300))  # clipped to +-MSE_CLIP before squaring: finite, ~ clip^2
    assert math.isfinite(huge["mse"])
    assert huge["mse"] == pytest.approx(metrics.MSE_CLIP**2, rel=1e-6)


def test_slopes_of_labels_and_cone():
    cones = metrics.cone_stats([np.array(CONE)])
    assert cones["slope_min"][0] == pytest.approx(0.1)
    assert cones["slope_max"][0] == pytest.approx(0.3)
    assert cones["slope_mean"][0] == pytest.approx(0.2)
    assert cones["width"][0] == pytest.approx(0.2)


def test_error_above_the_cone():
    r = one(pred_with_slope(0.5))
    assert not r["in_cone"]
    assert r["error_pct"] == pytest.approx(100 * 0.2 / 0.5)  # 40 %
    assert r["inacc_edge_pct"] == pytest.approx(100 * 0.2 / 0.2)  # 100 %
    assert r["inacc_mean_pct"] == pytest.approx(100 * 0.3 / 0.2)  # 150 %


def test_error_below_the_cone_uses_the_nearer_violated_edge():
    r = one(pred_with_slope(-0.1))
    assert r["error_pct"] == pytest.approx(100 * 0.2 / 0.1)  # |0.1 - (-0.1)| / 0.1 = 200 %
    assert r["inacc_edge_pct"] == pytest.approx(100.0)
    assert r["inacc_mean_pct"] == pytest.approx(150.0)


def test_inside_the_cone_scores_zero_error_but_not_zero_mean_inaccuracy():
    r = one(pred_with_slope(0.25, scale=7.0))
    assert r["in_cone"]
    assert r["error_pct"] == r["inacc_edge_pct"] == r["angle_to_cone_deg"] == 0.0
    assert r["inacc_mean_pct"] == pytest.approx(100 * 0.05 / 0.2)  # 25 %


def test_a_prediction_equal_to_a_label_is_inside():
    for lab in CONE:
        assert one(lab)["in_cone"]
        assert one(tuple(3.3 * v for v in lab))["in_cone"]


def test_correct_y_direction():
    pos, neg = [label(-0.2), label(-0.1)], [label(0.1), label(0.3)]  # y > 0, y < 0
    both, zero = [label(-0.1), label(0.2)], [label(0.0)]
    assert one((0.1, -1.0), pos)["correct_y"] and not one((-0.1, -1.0), pos)["correct_y"]
    assert one((-0.1, -1.0), neg)["correct_y"] and not one((0.1, -1.0), neg)["correct_y"]
    assert one((0.1, -1.0), both)["correct_y"] and one((-0.1, -1.0), both)["correct_y"]
    assert not one((0.0, -1.0), pos)["correct_y"]  # y_pred = 0 has neither sign
    assert one((0.0, -1.0), both)["correct_y"]
    assert one((0.0, -1.0), zero)["correct_y"] and not one((0.1, -1.0), zero)["correct_y"]
    assert one((5.0, 3.0), pos)["correct_y"]  # the y sign alone decides, even pointing away


def test_mse_of_the_raw_vector_against_each_label():
    labels = [(0.0, -1.0), (0.6, -0.8)]
    # (0.3, -0.9): squared errors (0.09 + 0.01) / 2 = 0.05 to each label.
    assert one((0.3, -0.9), labels)["mse"] == pytest.approx(0.05)
    # not normalised: (0, -2) -> ((0 + 1) / 2 + (0.36 + 1.44) / 2) / 2 = 0.7
    assert one((0.0, -2.0), labels)["mse"] == pytest.approx(0.7)


def test_angles():
    normal = [label(0.0)]
    r = one((1.0, -1.0), normal)
    assert r["angle_deg"] == pytest.approx(45.0)
    assert r["angle_to_mean_deg"] == pytest.approx(45.0)
    assert r["angle_to_cone_deg"] == pytest.approx(45.0)
    wide = [label(-1.0), label(1.0)]  # edges at +-45 degrees, mean slope 0
    assert one((1.0, 0.0), wide)["angle_to_cone_deg"] == pytest.approx(45.0)
    away = one((0.0, 1.0), wide)  # straight away from the object
    assert away["angle_to_mean_deg"] == pytest.approx(180.0)
    assert away["angle_to_cone_deg"] == pytest.approx(135.0)
    assert one((0.3, -1.0), wide)["angle_to_cone_deg"] == 0.0


def test_angle_to_the_cone_mean_uses_the_mean_slope():
    labels = [label(0.0), label(1.0)]  # mean slope 0.5: direction (-0.5, -1)
    expected = math.degrees(math.atan(0.5))
    assert one((0.0, -1.0), labels)["angle_to_mean_deg"] == pytest.approx(expected)


def test_medians_are_proper_medians_of_different_selections():
    # errors: inside, inside, 40 % (slope 0.5), 200 % (slope -0.1)
    preds = np.array([pred_with_slope(m) for m in (0.2, 0.15, 0.5, -0.1)])
    r = cone_metrics(preds, np.zeros(4, dtype=int), [np.array(CONE)])
    assert r["error_median_pct"] == pytest.approx(20.0)  # median of 0, 0, 40, 200
    assert r["error_mean_pct"] == pytest.approx(60.0)
    assert r["error_out_median_pct"] == pytest.approx(120.0)  # median of 40, 200
    assert r["error_out_mean_pct"] == pytest.approx(120.0)
    assert r["in_cone_pct"] == 50.0 and (r["n"], r["n_in_cone"], r["n_out"]) == (4, 2, 2)
    odd = cone_metrics(preds[1:], np.zeros(3, dtype=int), [np.array(CONE)])
    assert odd["error_median_pct"] == pytest.approx(40.0)
    assert odd["inacc_mean_median_pct"] == pytest.approx(150.0)  # of 25, 150, 150


def test_no_prediction_outside_any_cone_gives_zero_out_of_cone_summaries():
    r = cone_metrics(np.array([pred_with_slope(0.2)]), np.array([0]), [np.array(CONE)])
    assert r["n_out"] == 0
    assert r["error_out_median_pct"] == r["error_out_mean_pct"] == 0.0


def test_empty_prediction_set():
    with np.errstate(all="raise"):
        r = cone_metrics(np.zeros((0, 2)), np.zeros(0, dtype=int), [np.array(CONE)])
    assert r["n"] == 0 and all(r[k] == 0.0 for k in SUMMARY_KEYS)


def test_zero_width_cone_uses_eps_w():
    single = [label(0.2)]
    inside = one(pred_with_slope(0.2), single)
    assert inside["in_cone"] and inside["error_pct"] == 0.0 and inside["inacc_edge_pct"] == 0.0
    assert inside["inacc_mean_pct"] == pytest.approx(0.0, abs=1e-9)
    r = one(pred_with_slope(0.3), single + single)
    assert r["inacc_edge_pct"] == pytest.approx(100 * 0.1 / EPS_W)
    assert r["error_pct"] == pytest.approx(100 * 0.1 / 0.3)


def test_zero_and_tiny_y_prediction():
    r = one((0.0, -1.0))  # slope 0 below a cone at 0.1..0.3
    assert r["error_pct"] == pytest.approx(100 * 0.1 / EPS_M)
    tiny = one((1e-300, -1.0))
    assert tiny["error_pct"] == pytest.approx(100 * 0.1 / EPS_M)


def test_predictions_not_pressing_are_outside_every_pressing_cone():
    wide = [label(-50.0), label(50.0)]  # nearly tangential both ways
    for pred in [(0.0, 1.0), (0.0, 1e-300), (1.0, 0.0), (-1.0, 0.0), (0.2, 1.0), (-3.0, 0.1)]:
        r = one(pred, wide)
        assert not r["in_cone"], pred
        assert abs(r["slope"]) == pytest.approx(1 / EPS_Z)
        assert math.isfinite(r["error_pct"]) and math.isfinite(r["inacc_edge_pct"])


def test_zero_vector_reads_as_straight_into_the_pad():
    r = one((0.0, 0.0), [label(-0.1), label(0.1)])
    assert r["in_cone"] and r["slope"] == 0.0 and r["angle_deg"] == 0.0


def test_summary_per_configuration_with_a_mask():
    preds, cone_of, label_sets = random_case(7, n_configs=4, n_preds=40)
    full = cone_metrics(preds, cone_of, label_sets)
    for c in range(4):
        sub = cone_metrics(preds[cone_of == c], cone_of[cone_of == c], label_sets)
        masked = summarize(full["per_sample"], cone_of == c)
        for key in SUMMARY_KEYS:
            assert masked[key] == pytest.approx(sub[key], rel=1e-12), key


def test_torch_tensors_score_as_their_numpy_values():
    torch = pytest.importorskip("torch")
    preds, cone_of, label_sets = random_case(3, n_configs=5, n_preds=30)
    expected = cone_metrics(preds, cone_of, label_sets)
    pred = torch.tensor(preds, requires_grad=True)  # a model's output, still in the graph
    got = cone_metrics(pred, torch.tensor(cone_of), [torch.tensor(s) for s in label_sets])
    assert got["n"] == expected["n"] == 30
    for key in SUMMARY_KEYS:
        assert got[key] == pytest.approx(expected[key], rel=1e-12, abs=1e-12), key
    for key, values in expected["per_sample"].items():
        np.testing.assert_allclose(got["per_sample"][key], values, rtol=1e-12, err_msg=key)


@pytest.mark.parametrize(
    ("pred", "cone_of", "label_sets", "match"),
    [
        ([[np.nan, -1.0]], [0], [CONE], "non-finite"),
        ([[np.inf, -1.0]], [0], [CONE], "non-finite"),
        ([[0.1, -1.0]], [0], [[(0.0, np.nan)]], "non-finite"),
        ([[0.1, -1.0, 0.0]], [0], [CONE], "shape"),
        ([[0.1, -1.0]], [0, 0], [CONE], "shape"),
        ([[0.1, -1.0]], [1], [CONE], "cone_of must lie"),
        ([[0.1, -1.0]], [0.0], [CONE], "integers"),
        ([[0.1, -1.0]], [1], [CONE, np.zeros((0, 2))], "empty"),
    ],
)
def test_bad_input_raises(pred, cone_of, label_sets, match):
    with pytest.raises(ValueError, match=match):
        cone_metrics(np.array(pred), np.array(cone_of), [np.asarray(s) for s in label_sets])


def test_unreferenced_empty_label_set_is_allowed():
    r = cone_metrics(np.array([[0.1, -1.0]]), np.array([0]), [np.array(CONE), np.zeros((0, 2))])
    assert r["n"] == 1
