"""Tests of the cone metrics: a slow reference, hand-computed cases and property tests."""

from __future__ import annotations

import math
import statistics

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from vistac_learn import metrics
from vistac_learn.metrics import EPS_M, EPS_W, EPS_Z, cone_metrics, per_sample_metrics, summarize

SUMMARY_KEYS = (
    "correct_y_pct", "in_cone_pct", "error_median_pct", "error_mean_pct", "error_out_median_pct",
    "error_out_mean_pct", "inacc_edge_median_pct", "inacc_edge_mean_pct", "inacc_mean_median_pct",
    "inacc_mean_mean_pct", "mse_mean", "angle_to_mean_median_deg", "angle_to_mean_mean_deg",
    "angle_to_cone_median_deg", "angle_to_cone_mean_deg",
)  # fmt: skip
CONE_KEYS = (  # per-sample metrics that depend only on the prediction's direction
    "slope", "angle_deg", "correct_y", "in_cone", "error_pct", "inacc_edge_pct",
    "inacc_mean_pct", "angle_to_mean_deg", "angle_to_cone_deg",
)  # fmt: skip
PROPERTY_SETTINGS = settings(
    max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow]
)


def label(m: float) -> tuple[float, float]:
    """Unit label (y, z) with z < 0 and slope y / z = m."""
    z = -1.0 / math.sqrt(1.0 + m * m)
    return (m * z, z)


def pred_with_slope(m: float, scale: float = 1.0) -> tuple[float, float]:
    """A prediction pressing into the pad (z = -scale) with slope m."""
    return (-m * scale, -scale)


# --------------------------------------------------------------------------------------------
# Slow, obvious reference: loops over plain floats, following the module's stated conventions.
# --------------------------------------------------------------------------------------------


def ref_slope(y: float, z: float) -> float:
    """m = y / z; zero vector -> 0; z / |v| > -EPS_Z -> -sign(y) / EPS_Z with sign(0) = +1."""
    if y == 0.0 and z == 0.0:
        return 0.0
    if z / math.hypot(y, z) <= -EPS_Z:
        return y / z
    return (1.0 if y < 0 else -1.0) / EPS_Z


def ref_angle(y: float, z: float) -> float:
    """Degrees of (y, z) from the into-the-pad axis; zero vector -> 0."""
    if y == 0.0 and z == 0.0:
        return 0.0
    return math.degrees(math.atan2(y, -z))


def ref_angle_between(a: float, b: float) -> float:
    d = abs(a - b) % 360.0
    return min(d, 360.0 - d)


def ref_sign(v: float) -> int:
    return (v > 0) - (v < 0)


def ref_metrics(preds, cone_of, label_sets):
    """Per-sample dicts and a summary dict, computed one prediction at a time."""
    rows = []
    for (py, pz), c in zip(preds, cone_of, strict=True):
        labels = label_sets[c]
        ms = [ref_slope(y, z) for y, z in labels]
        lo, hi, mean = min(ms), max(ms), sum(ms) / len(ms)
        width = hi - lo
        m = ref_slope(py, pz)
        tol_lo = 1e-9 * max(1.0, abs(lo))
        tol_hi = 1e-9 * max(1.0, abs(hi))
        if m < lo - tol_lo:
            inside, dist = False, lo - m
        elif m > hi + tol_hi:
            inside, dist = False, m - hi
        else:
            inside, dist = True, 0.0
        signs = [ref_sign(y) for y, _ in labels]
        w_eff = width if width > EPS_W else EPS_W
        angle = ref_angle(py, pz)
        edge_angles = [math.degrees(math.atan(-lo)), math.degrees(math.atan(-hi))]
        mean_angle = math.degrees(math.atan2(-mean, 1.0))
        sq = 0.0
        cy, cz = (max(-1e100, min(1e100, v)) for v in (py, pz))  # MSE_CLIP
        for ly, lz in labels:
            sq += ((cy - ly) ** 2 + (cz - lz) ** 2) / 2.0
        rows.append({
            "slope": m,
            "angle_deg": angle,
            "correct_y": min(signs) <= ref_sign(py) <= max(signs),
            "in_cone": inside,
            "error_pct": 100.0 * dist / max(abs(m), EPS_M),
            "inacc_edge_pct": 100.0 * dist / w_eff,
            "inacc_mean_pct": 100.0 * abs(m - mean) / w_eff,
            "mse": sq / len(labels),
            "angle_to_mean_deg": ref_angle_between(angle, mean_angle),
            "angle_to_cone_deg": 0.0 if inside else min(
                ref_angle_between(angle, a) for a in edge_angles),
        })  # fmt: skip

    def med(values):
        return statistics.median(values) if values else 0.0

    def avg(values):
        return statistics.fmean(values) if values else 0.0

    def col(key, only_out=False):
        return [r[key] for r in rows if not (only_out and r["in_cone"])]

    summary = {
        "correct_y_pct": 100.0 * avg([float(v) for v in col("correct_y")]),
        "in_cone_pct": 100.0 * avg([float(v) for v in col("in_cone")]),
        "error_median_pct": med(col("error_pct")),
        "error_mean_pct": avg(col("error_pct")),
        "error_out_median_pct": med(col("error_pct", only_out=True)),
        "error_out_mean_pct": avg(col("error_pct", only_out=True)),
        "inacc_edge_median_pct": med(col("inacc_edge_pct")),
        "inacc_edge_mean_pct": avg(col("inacc_edge_pct")),
        "inacc_mean_median_pct": med(col("inacc_mean_pct")),
        "inacc_mean_mean_pct": avg(col("inacc_mean_pct")),
        "mse_mean": avg(col("mse")),
        "angle_to_mean_median_deg": med(col("angle_to_mean_deg")),
        "angle_to_mean_mean_deg": avg(col("angle_to_mean_deg")),
        "angle_to_cone_median_deg": med(col("angle_to_cone_deg")),
        "angle_to_cone_mean_deg": avg(col("angle_to_cone_deg")),
    }
    return rows, summary


def random_case(seed: int, n_configs: int = 25, n_preds: int = 300):
    """Configurations of 1-8 noisy labels (some identical), predictions incl. special values."""
    rng = np.random.default_rng(seed)
    label_sets = []
    for i in range(n_configs):
        k = int(rng.integers(1, 9))
        centre = rng.uniform(-1.3, 1.3)  # radians from the normal
        angles = centre + rng.normal(0.0, 0.15, k)
        if i % 5 == 0:
            angles[:] = centre  # identical repeats: zero width
        label_sets.append(np.stack([np.sin(angles), -np.cos(angles)], axis=1))
    preds = rng.normal(0.0, 1.0, (n_preds, 2)) * rng.choice([1e-3, 1.0, 10.0], (n_preds, 1))
    preds[:, 1] -= 0.8 * np.abs(preds[:, 1])  # mostly pressing, some pointing away
    special = [(0.0, 0.0), (0.0, -1.0), (1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (1e-300, -1e-300),
               (0.3, 1e-300), (5e-324, -1.0), (1e300, -2e300), (-1e-8, -1.0)]  # fmt: skip
    preds[: len(special)] = special
    cone_of = rng.integers(0, n_configs, n_preds)
    return preds, cone_of, label_sets


def assert_close_to_reference(preds, cone_of, label_sets, rtol=1e-9, atol=1e-9):
    ref_rows, ref_summary = ref_metrics(
        [tuple(map(float, p)) for p in preds], [int(c) for c in cone_of],
        [[tuple(map(float, lab)) for lab in labels] for labels in label_sets],
    )  # fmt: skip
    result = cone_metrics(preds, cone_of, label_sets)
    for key in ref_rows[0]:
        expected = np.array([r[key] for r in ref_rows])
        actual = result["per_sample"][key]
        if expected.dtype == bool:
            np.testing.assert_array_equal(actual, expected, err_msg=key)
        else:
            np.testing.assert_allclose(actual, expected, rtol=rtol, atol=atol, err_msg=key)
    for key in SUMMARY_KEYS:
        assert result[key] == pytest.approx(ref_summary[key], rel=rtol, abs=atol), key


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

CONE = [label(0.1), label(0.2), label(0.3)]  # slopes 0.1..0.3, mean 0.2, width 0.2


def one(pred, labels=CONE):
    """Per-sample metrics of a single prediction against one cone, as Python scalars."""
    ps = per_sample_metrics(np.array([pred]), np.array([0]), [np.array(labels)])
    return {k: v[0].item() for k, v in ps.items()}


def test_documented_constants():
    assert (EPS_Z, EPS_M, EPS_W) == (1e-6, 1e-6, 1e-3)
    assert (metrics.IN_CONE_RTOL, metrics.MSE_CLIP) == (1e-9, 1e100)


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


def test_torch_tensors_are_accepted():
    torch = pytest.importorskip("torch")
    pred = torch.tensor([[0.1, -1.0]], requires_grad=True)
    r = cone_metrics(pred, torch.tensor([0]), [torch.tensor(CONE)])
    assert r["n"] == 1


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
