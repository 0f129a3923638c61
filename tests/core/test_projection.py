"""The one projection (`vistac.projection`): the plain top view exactly as the dataset format
writes it, a perspective camera's image directions, the configuration columns round trip, and
the drawn overlay's displacement. (That MuJoCo's renderer draws what it projects is
tests/sim/test_projection_render.py.)"""

from __future__ import annotations

import numpy as np
import pytest

from vistac.projection import (
    CAMERA_COLUMNS,
    Projection,
    displace,
    overlay_columns,
    overlay_from_columns,
)

PHONE = Projection(227, 1418.75 / 1.05, (0.004, -0.003), tilt=np.radians(5.0),
                   tilt_azimuth=2.3, roll=np.radians(-5.0), fovy=np.radians(70.0))


def _points(n: int = 50, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.concatenate([rng.uniform(-0.08, 0.08, (n, 2)), rng.uniform(0, 0.03, (n, 1))], 1)


def test_the_plain_top_view_is_the_dataset_formats_formula_bit_for_bit():
    """docs/dataset-format.md: u = (x - camera_x) px_per_m + W/2, v = H/2 - (y - camera_y)
    px_per_m, whatever the height; a direction is (x, -y)."""
    proj = Projection(227, 1418.75, (0.01, -0.02))
    p = _points()
    got = proj.project(p)
    assert np.array_equal(got[:, 0], (p[:, 0] - 0.01) * 1418.75 + 227 / 2)
    assert np.array_equal(got[:, 1], -(p[:, 1] + 0.02) * 1418.75 + 227 / 2)
    v = _points(seed=1)
    assert np.array_equal(proj.direction(p, v), np.stack([v[:, 0], -v[:, 1]], 1))


@pytest.mark.parametrize("proj", [PHONE, Projection(227, 1418.75, (0.01, 0.0), np.radians(4.0),
                                                    1.0, np.radians(3.0))],
                         ids=["phone camera", "tilted orthographic"])
def test_image_directions_are_the_projections_derivative(proj):
    p, v = _points(), _points(seed=2) - 0.01
    eps = 1e-7
    finite = (proj.project(p + eps * v) - proj.project(p - eps * v)) / (2 * eps)
    got = proj.direction(p, v)
    unit = got / np.linalg.norm(got, axis=1, keepdims=True)
    np.testing.assert_allclose(unit, finite / np.linalg.norm(finite, axis=1, keepdims=True),
                               atol=1e-6)
    assert (np.einsum("ij,ij->i", got, finite) > 0).all()


def test_the_phone_camera_sees_height_and_tilt():
    """A point above the table is seen farther from the centre (perspective); the tilted and
    rolled camera still puts `center` in the middle of the image."""
    flat = Projection(227, 1418.75, fovy=np.radians(60.0))
    low, high = flat.project(np.array([[0.04, 0.0, 0.0], [0.04, 0.0, 0.03]]))
    assert high[0] - 113.5 > (low[0] - 113.5) * 1.05
    np.testing.assert_allclose(PHONE.project(np.array([*PHONE.center, 0.0])), [113.5, 113.5],
                               atol=1e-9)


def test_columns_give_back_the_camera():
    """`Projection.from_columns` of `columns` (+ `perspective_columns`) projects as the camera
    did; absent or NaN angle columns are the plain top view."""
    for proj in (PHONE, Projection(96, 600.0, (0.002, 0.001), np.radians(3.0), 0.5, 0.1)):
        row = proj.columns() | proj.perspective_columns()
        assert set(CAMERA_COLUMNS) - set(row) <= {"camera_fovy_deg"}
        back = Projection.from_columns(row, proj.image_size)
        np.testing.assert_allclose(back.project(_points()), proj.project(_points()), atol=1e-9)
    plain = Projection.from_columns({"camera_x": 0.0, "camera_y": 0.0, "px_per_m": 500.0,
                                     "camera_roll_deg": float("nan")}, 64)
    assert plain == Projection(64, 500.0)


def test_the_drawn_overlay_turns_about_the_pivot_then_shifts():
    pivot = np.array([0.01, 0.02, 0.012])
    overlay = (0.003, -0.002, np.radians(90.0))
    moved = displace(np.array([pivot, pivot + [0.01, 0.0, 0.0]]), pivot, overlay)
    np.testing.assert_allclose(moved, [pivot + [0.003, -0.002, 0], pivot + [0.003, 0.008, 0]],
                               atol=1e-12)
    back = overlay_from_columns(overlay_columns("thumb", overlay), "thumb")
    np.testing.assert_allclose(back, overlay, atol=1e-15)
    assert overlay_from_columns({}, "index") == (0.0, 0.0, 0.0)
