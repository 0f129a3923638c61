"""vistac_learn.data.perturb: each axis changes what it says and nothing else, seeded."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from vistac.errors import UserError
from vistac_learn.data.perturb import (
    AXES,
    FINGER_LABEL,
    OBJECT,
    PERTURBATIONS,
    REGION_AXES,
    TABLE,
    Scene,
    check_names,
    is_flat_render,
    map_direction,
    map_points,
    perturb,
    random_axes,
    segment,
)

FINGER_RGB = {"index": (0.0, 0.85, 0.0), "thumb": (0.9, 0.0, 0.0)}
TABLE_RGB = (0.81, 0.81, 0.81)


def _render() -> np.ndarray:
    """A flat four-colour render like the simulator's: table, object, two finger capsules."""
    img = np.full((120, 120, 3), 207, np.uint8)
    cv2.circle(img, (60, 60), 18, (176, 157, 107), -1)
    cv2.line(img, (0, 30), (40, 52), (0, 255, 0), 14)
    cv2.line(img, (119, 95), (80, 68), (255, 0, 0), 14)
    return img


@pytest.fixture(scope="module")
def scene():
    img = _render()
    return img, Scene(segment(img, FINGER_RGB, TABLE_RGB), FINGER_RGB)


def test_segment_recovers_the_flat_regions(scene):
    img, sc = scene
    lab = sc.labels
    assert lab[5, 110] == TABLE and lab[60, 60] == OBJECT
    assert lab[30, 2] == FINGER_LABEL["index"] and lab[95, 117] == FINGER_LABEL["thumb"]
    # every pixel of exactly the overlay colour is its finger, nothing else is
    green = (img == (0, 255, 0)).all(axis=2)
    assert np.array_equal(green, lab == FINGER_LABEL["index"])


@pytest.mark.parametrize("name", PERTURBATIONS)
def test_each_perturbation_is_seeded_and_changes_the_image(scene, name):
    img, sc = scene
    a = perturb(name, img, sc, np.random.default_rng(3))
    b = perturb(name, img, sc, np.random.default_rng(3))
    c = perturb(name, img, sc, np.random.default_rng(4))
    assert a.rgb.shape == img.shape and a.rgb.dtype == np.uint8
    np.testing.assert_array_equal(a.rgb, b.rgb)
    assert not np.array_equal(a.rgb, img) and not np.array_equal(a.rgb, c.rgb)
    if name not in ("tilt", "all"):
        np.testing.assert_array_equal(a.homography, np.eye(3))


@pytest.mark.parametrize(("name", "region"), [("table", TABLE), ("object", OBJECT)])
def test_texture_axes_touch_only_their_region(scene, name, region):
    img, sc = scene
    out = perturb(name, img, sc, np.random.default_rng(0)).rgb
    changed = (out != img).any(axis=2)
    assert changed[sc.labels == region].mean() > 0.5
    assert not changed[sc.labels != region].any()


def test_overlay_axis_keeps_the_fingers_where_they_are(scene):
    img, sc = scene
    for seed in range(5):
        out = perturb("overlay", img, sc, np.random.default_rng(seed)).rgb
        hsv = cv2.cvtColor(out, cv2.COLOR_RGB2HSV_FULL)
        for f, (v, u) in {"index": (40, 20), "thumb": (82, 100)}.items():
            # the centre line of each finger keeps a saturated colour near its nominal hue
            hue = float(hsv[v, u, 0]) * 360 / 256
            ref = 120 if f == "index" else 0
            assert abs((hue - ref + 180) % 360 - 180) <= 25 and hsv[v, u, 1] > 120


def test_tilt_moves_points_by_its_homography(scene):
    img = np.zeros((120, 120, 3), np.uint8)
    img[30:33, 80:83] = 255  # a bright dot at (81, 31)
    labels = np.zeros(img.shape[:2], np.uint8)
    out = perturb("tilt", img, Scene(labels, FINGER_RGB), np.random.default_rng(1))
    assert not np.allclose(out.homography, np.eye(3))
    v, u = np.nonzero(out.rgb[..., 0] > 60)
    w = out.rgb[v, u, 0].astype(float)
    found = np.array([(u * w).sum(), (v * w).sum()]) / w.sum()
    np.testing.assert_allclose(found, map_points(out.homography, [[81, 31]])[0], atol=0.3)
    d = map_direction(out.homography, np.array([60.0, 60.0]), np.array([1.0, 0.0]))
    assert abs(np.hypot(*d) - 1) < 1e-9 and d[0] > 0.99  # a few degrees at most


def test_bad_input_is_a_user_error(scene):
    img, sc = scene
    with pytest.raises(UserError, match="unknown perturbation 'fog'"):
        perturb("fog", img, sc, np.random.default_rng(0))
    with pytest.raises(UserError, match="do not match"):
        perturb("light", img[:50], sc, np.random.default_rng(0))
    with pytest.raises(UserError, match="uint8"):
        segment(img.astype(np.float32), FINGER_RGB, TABLE_RGB)
    assert check_names(["none", "tilt", ""]) == ("tilt",)


def test_random_axes_draws_a_nonempty_subset():
    rng = np.random.default_rng(0)
    draws = [random_axes(rng) for _ in range(200)]
    assert all(d and set(d) <= set(AXES) for d in draws)
    assert {a for d in draws for a in d} == set(AXES) and len(set(draws)) > 20


def test_a_photograph_is_augmented_along_the_image_axes_only(scene):
    """Table, object and overlay need the regions of a flat render; a photograph (no bare
    table colour) gets light, tilt and camera only, and a flat render every axis as before."""
    img, sc = scene
    assert is_flat_render(sc.labels)
    photo = np.random.default_rng(1).integers(0, 256, img.shape, dtype=np.uint8)
    assert not is_flat_render(segment(photo, FINGER_RGB, TABLE_RGB))
    draws = [random_axes(np.random.default_rng(k), 0.5, flat=False) for k in range(200)]
    assert all(d and not set(d) & set(REGION_AXES) for d in draws)
    assert {a for d in draws for a in d} == set(AXES) - set(REGION_AXES)
    same = [random_axes(np.random.default_rng(k), 0.5) for k in range(50)]
    assert same == [random_axes(np.random.default_rng(k), 0.5, flat=True) for k in range(50)]
