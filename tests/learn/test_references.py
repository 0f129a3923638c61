"""The references of an evaluation: the pinch baseline on a hand-built scene, the noise floor,
and both in `evaluate`'s output."""

from __future__ import annotations

import json
import shutil

import cv2
import numpy as np
import pandas as pd
import pytest
from learn_fixtures import INDEX_RGB, TABLE, THUMB_RGB, make_dataset

from vistac.cli import main
from vistac.dataset import open_tables
from vistac_learn.data.variants import rotation_matrix
from vistac_learn.evaluate import references as refs_mod
from vistac_learn.evaluate.config import EvaluateCfg
from vistac_learn.evaluate.geometric import sensor_direction
from vistac_learn.evaluate.pinch import clamp_to_cone, predict_image
from vistac_learn.evaluate.references import has_clean_forces, noise_floor, references
from vistac_learn.evaluate.run import evaluate_run
from vistac_learn.train.config import protocol_cfg
from vistac_learn.train.loop import train_run_folder

COLOURS = {"index": INDEX_RGB, "thumb": THUMB_RGB}
SHIFT = 4  # OpenCV's sub-pixel drawing: coordinates in 1/16 px


def _rgb255(rgb) -> tuple[int, int, int]:
    return tuple(int(round(c * 255)) for c in rgb)


def _fixed(p) -> tuple[int, int]:
    return tuple(int(round(c * (1 << SHIFT))) for c in p)


def _capsule(img, p0, p1, r, rgb) -> None:
    """A filled capsule from p0 to p1 (pixel centres at integers), radius r (pixels)."""
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    d = (p1 - p0) / np.hypot(*(p1 - p0))
    n = np.array([-d[1], d[0]]) * r
    col = _rgb255(rgb)
    for p in (p0, p1):
        cv2.circle(img, _fixed(p), int(round(r * (1 << SHIFT))), col, -1, cv2.LINE_8, SHIFT)
    quad = np.array([_fixed(q) for q in (p0 + n, p1 + n, p1 - n, p0 - n)], np.int32)
    cv2.fillConvexPoly(img, quad, col, cv2.LINE_8, SHIFT)


def _unit(v) -> np.ndarray:
    v = np.asarray(v, float)
    return v / np.hypot(*v)


def _turn(v, deg) -> np.ndarray:
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1]])


def box_scene(yaw_deg: float, index_off: float, thumb_off: float, tilt_index: float,
              tilt_thumb: float, size: int = 227, r: float = 13.5):
    """Two fingers pressing a box on opposite faces, drawn like the simulator's top view.

    The box (80 x 56 px) is turned by `yaw_deg`; the index presses its +x face at `index_off`
    px from the face's middle, the thumb its -x face at `thumb_off`; each finger's axis is its
    face's inward normal turned by `tilt_*` degrees. Returns the image and, per finger, its
    contact point, outward normal and axis (pixels, image coordinates).
    """
    img = np.empty((size, size, 3), np.uint8)
    img[:] = _rgb255(TABLE)
    centre = np.array([size / 2, size / 2])
    ex, ey = _turn((1.0, 0.0), yaw_deg), _turn((0.0, 1.0), yaw_deg)
    corners = [centre + sx * 40 * ex + sy * 28 * ey for sx, sy in ((-1, -1), (1, -1), (1, 1),
                                                                   (-1, 1))]
    cv2.fillConvexPoly(img, np.array([_fixed(c) for c in corners], np.int32),
                       _rgb255((0.55, 0.35, 0.2)), cv2.LINE_8, SHIFT)
    scene = {}
    for f, side, off, tilt in (("index", 1, index_off, tilt_index),
                               ("thumb", -1, thumb_off, tilt_thumb)):
        normal = side * ex
        contact = centre + side * 40 * ex + off * ey
        axis = _turn(-normal, tilt)
        tip = contact + r * normal
        _capsule(img, tip, tip - 70 * axis, r, COLOURS[f])
        scene[f] = (contact, normal, axis)
    return img, scene


def expected_label(scene: dict, finger: str, friction: float) -> np.ndarray:
    """The physics the baseline encodes, from the scene's true geometry."""
    other = "thumb" if finger == "index" else "index"
    contact, normal, axis = scene[finger]
    d = clamp_to_cone(_unit(contact - scene[other][0]), normal, friction)
    return sensor_direction(d, axis, finger)


def _angle_deg(a, b) -> float:
    return float(np.degrees(np.arccos(np.clip(_unit(a) @ _unit(b), -1, 1))))


@pytest.mark.parametrize("yaw,index_off,thumb_off,tilts,friction", [
    (0.0, 6.0, -5.0, (12.0, -8.0), 0.8),  # sticking: the closing axis, not the normal
    (27.0, -9.0, 8.0, (-15.0, 10.0), 0.8),
    (-41.0, 15.0, -16.0, (5.0, 18.0), 0.2),  # slipping: the axis lies outside the cone
])
def test_pinch_recovers_the_label_of_a_drawn_box(yaw, index_off, thumb_off, tilts, friction):
    img, scene = box_scene(yaw, index_off, thumb_off, *tilts)
    pred, failures = predict_image(img, COLOURS, ("index", "thumb"), friction)
    assert failures == 0
    for i, f in enumerate(("index", "thumb")):
        want = expected_label(scene, f, friction)
        # on 40 random such scenes: contacts within 0.35 px across the closing axis, the
        # finger's axis within 0.2 deg, labels within 0.45 deg
        assert _angle_deg(pred[2 * i:2 * i + 2], want) < 0.6, f
        np.testing.assert_allclose(np.hypot(*pred[2 * i:2 * i + 2]), 1.0)
        if friction == 0.2:  # slipping: on the cone's edge, atan(0.2) = 11.3 deg off the normal
            normal = sensor_direction(scene[f][1], scene[f][2], f)
            assert _angle_deg(pred[2 * i:2 * i + 2], normal) == pytest.approx(
                np.degrees(np.arctan(0.2)), abs=0.6)
            assert _angle_deg(want, normal) == pytest.approx(np.degrees(np.arctan(0.2)))


def test_clamp_to_cone():
    n = np.array([0.0, 1.0])
    inside = _unit((0.3, 1.0))
    np.testing.assert_array_equal(clamp_to_cone(inside, n, 0.5), inside)
    for sign in (1, -1):
        out = clamp_to_cone(_unit((sign * 2.0, 1.0)), n, 0.5)
        assert np.hypot(*out) == pytest.approx(1.0)
        assert out[0] * sign > 0  # turned towards the normal, staying on its side
        assert _angle_deg(out, n) == pytest.approx(np.degrees(np.arctan(0.5)))


def test_missing_fingers_fall_back_straight_into_the_pad():
    img = np.full((64, 64, 3), 207, np.uint8)
    pred, failures = predict_image(img, COLOURS, ("index", "thumb"), 0.8)
    assert failures == 2 and tuple(pred) == (0.0, -1.0, 0.0, -1.0)


def test_noise_floor_is_zero_without_noise_and_positive_with_it(tmp_path):
    clean = open_tables(make_dataset(tmp_path / "clean", n=8, repeats=4, size=64, noise=0.0))
    fl = noise_floor(clean, clean.rows(None), ("index", "thumb"))
    for f in ("index", "thumb"):
        assert fl[f]["angle_to_mean_median_deg"] == pytest.approx(0.0, abs=1e-6)
        assert fl[f]["angle_to_mean_mean_deg"] == pytest.approx(0.0, abs=1e-6)
        assert fl[f]["in_cone_pct"] == 100.0 and fl[f]["mse_mean"] == pytest.approx(0.0, abs=1e-12)
    noisy = open_tables(make_dataset(tmp_path / "noisy", n=8, repeats=4, size=64, noise=0.05))
    fl = noise_floor(noisy, noisy.rows(None), ("index",))
    assert 0.1 < fl["index"]["angle_to_mean_median_deg"] < 5.0


def test_no_references_for_data_without_clean_forces(tmp_path):
    root = make_dataset(tmp_path / "real", n=6, repeats=2, size=64)
    configs = pd.read_parquet(root / "configs.parquet")
    configs.drop(columns=[c for c in configs if c.startswith("force_clean_")]).to_parquet(
        root / "configs.parquet", index=False)
    t = open_tables(root)
    assert not has_clean_forces(t, ("index",))
    assert references(t, t.rows(None), ("index",)) is None


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    root = tmp_path_factory.mktemp("refs")
    ds = make_dataset(root / "ds", n=8, repeats=3, size=64, splits=(0.5, 0.25, 0.25))
    cfg = protocol_cfg("study", str(ds), str(root / "run"), model="smallconv", epochs=1,
                       n_rotations=2, batch_size=4, device="cpu", finger="both",
                       variant="edge-crop",
                       cache_dir=str(root / "cache"))
    return ds, train_run_folder(cfg, progress=False)


def test_evaluate_shows_the_references_beside_the_model(tiny_run, monkeypatch):
    ds, run = tiny_run
    res = evaluate_run(EvaluateCfg(run=str(run), no_plots=True))
    saved = json.loads((run / "eval" / "test" / "metrics.json").read_text())
    assert set(saved["metrics"]) == {"index", "thumb"}  # the contract's layout, unchanged
    for r in (res, saved):
        assert set(r["references"]) == {"noise_floor", "pinch"}
        for k in ("noise_floor", "pinch"):
            assert set(r["references"][k]["metrics"]) == {"index", "thumb"}
            assert np.isfinite(r["references"][k]["metrics"]["index"]["angle_to_mean_median_deg"])
        assert r["references"]["pinch"]["ms_per_image"] > 0
        for label in ("noise floor (clean force) (index)", "pinch baseline (thumb)"):
            assert label in r["table"]
    # the pinch reference is cached: a second evaluation does not run the baseline again
    monkeypatch.setattr(refs_mod, "pinch_predictions", lambda *a, **k: pytest.fail("recomputed"))
    again = evaluate_run(EvaluateCfg(run=str(run), no_plots=True))
    assert again["references"]["pinch"] == res["references"]["pinch"]
    bare = evaluate_run(EvaluateCfg(run=str(run), no_plots=True, no_references=True))
    assert "references" not in bare and "noise floor" not in bare["table"]


def test_cli_baseline_pinch(tiny_run, tmp_path, capsys):
    ds, _ = tiny_run
    out = tmp_path / "pinch"
    rc = main(["evaluate", "--baseline", "pinch", "--data", str(ds), "--out", str(out),
               "--finger", "both", "--rotations", "fixed", "--n-rotations", "3", "--no-plots"])
    assert rc == 0
    printed = capsys.readouterr().out
    assert "| pinch baseline (index) |" in printed and "| noise floor (clean force) (index) |" \
        in printed
    saved = json.loads((out / "metrics.json").read_text())
    assert saved["baseline"] == "pinch" and saved["n_predictions"] == 2 * 3
    assert saved["settings"]["friction"] is None  # the dataset's (fixture: no physics: 0.8)


def test_demo_report_shows_the_references(tiny_run, tmp_path):
    from vistac_learn.demo import write_report
    from vistac_learn.evaluate.run import evaluate_baseline

    ds, run = tiny_run
    evaluate_run(EvaluateCfg(run=str(run), no_plots=True))
    evaluate_baseline(EvaluateCfg(baseline="geometric", data=str(ds), finger="both",
                                  rotations="none", n_rotations=1, no_plots=True),
                      tmp_path / "baseline")
    data = tmp_path / "data"  # the report reads the counts a generated manifest holds
    shutil.copytree(ds, data)
    manifest = json.loads((data / "manifest.json").read_text())
    manifest["counts"] |= {"split": {"train": 4, "val": 2, "test": 2}, "objects": 4}
    (data / "manifest.json").write_text(json.dumps(manifest))
    text = write_report(tmp_path, data, run, 0.0, 0.0).read_text()
    for row in ("| geometric baseline (index) |", "| noise floor (clean force) (thumb) |",
                "| pinch baseline (index) |", "| smallconv, edge-crop (thumb) |"):
        assert text.count(row) == 1, row


def test_the_pinch_cache_follows_the_labels(tmp_path):
    t = open_tables(make_dataset(tmp_path / "ds", n=4, repeats=2, size=64))
    rows = t.rows(None)
    first = refs_mod.pinch_reference(t, rows, ("index",), cache_dir=tmp_path / "cache")
    assert len(list((tmp_path / "cache").glob("pinch-*.json"))) == 1
    t.cones["index"][0] = -t.cones["index"][0]  # other labels, same images and configurations
    second = refs_mod.pinch_reference(t, rows, ("index",), cache_dir=tmp_path / "cache")
    assert len(list((tmp_path / "cache").glob("pinch-*.json"))) == 2
    assert second["metrics"] != first["metrics"]


def test_the_pinch_cache_follows_the_locator(tmp_path, monkeypatch):
    """The pinch baseline locates the fingers itself: a new locator version or other segmenter
    weights must not be served the old locator's results."""
    import vistac_learn.data.fingertips as fingertips
    import vistac_learn.data.segmenter as segmenter
    from vistac_learn.evaluate.pinch import PinchCfg

    t = open_tables(make_dataset(tmp_path / "ds", n=4, repeats=2, size=64))
    rows, key = t.rows(None), ("index",)
    before = refs_mod._cache_path(t, rows, key, PinchCfg(), tmp_path)
    monkeypatch.setattr(segmenter, "weights_digest", lambda *a, **k: "other weights")
    weights = refs_mod._cache_path(t, rows, key, PinchCfg(), tmp_path)
    monkeypatch.setattr(fingertips, "LOCATOR_VERSION", fingertips.LOCATOR_VERSION + 1)
    version = refs_mod._cache_path(t, rows, key, PinchCfg(), tmp_path)
    assert len({before, weights, version}) == 3


@pytest.mark.parametrize("angle", [25.0, 130.0])
def test_pinch_label_survives_a_rotated_image(angle):
    """A rotated image (bilinear: mixed colours along every edge) gives the same sensor-frame
    label: the frames turn with the image."""
    img, scene = box_scene(10.0, 6.0, -7.0, 12.0, -9.0)
    h, w = img.shape[:2]
    rot = cv2.warpAffine(img, rotation_matrix(angle, w, h), (w, h), flags=cv2.INTER_LINEAR,
                         borderMode=cv2.BORDER_CONSTANT, borderValue=_rgb255(TABLE))
    pred, failures = predict_image(rot, COLOURS, ("index", "thumb"), 0.8)
    assert failures == 0
    for i, f in enumerate(("index", "thumb")):
        assert _angle_deg(pred[2 * i:2 * i + 2], expected_label(scene, f, 0.8)) < 1.0, f


def test_pinch_reads_a_photograph_through_the_segmenter_and_a_flat_render_by_colour(monkeypatch):
    """Default (`PinchCfg.segmented` None): a flat render by its colours (the exact outline),
    anything else (here camera noise) through the learned segmenter."""
    from vistac_learn.data import segmenter
    from vistac_learn.evaluate.pinch import PinchCfg

    img, _ = box_scene(0.0, 6.0, -5.0, 12.0, -8.0)
    calls = []
    real = segmenter.segment_image
    monkeypatch.setattr(segmenter, "segment_image", lambda *a: calls.append(1) or real(*a))
    plain, _ = predict_image(img, COLOURS, ("index", "thumb"), 0.8, PinchCfg(segmented=False))
    auto, _ = predict_image(img, COLOURS, ("index", "thumb"), 0.8)
    assert not calls and np.array_equal(plain, auto)
    noisy = np.clip(img + np.random.default_rng(0).normal(0, 4, img.shape), 0, 255)
    predict_image(noisy.astype(np.uint8), COLOURS, ("index", "thumb"), 0.8)
    assert calls
