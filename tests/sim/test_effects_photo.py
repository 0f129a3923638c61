"""The appearance effects of the `photo` preset, one test (or a few) each; masks; labels that do
not change when only the appearance does."""

from __future__ import annotations

import dataclasses
import json

import cv2
import numpy as np
import pandas as pd
import pytest
from pressed_scenes import pressed_scene

from vistac.cli import main
from vistac.dataset import open_tables
from vistac.errors import UserError
from vistac.textures import BANK_PHOTOS
from vistac_sim.effects import EffectsCfg, build_pipeline
from vistac_sim.effects.blur import Blur, BlurCfg
from vistac_sim.effects.drawn_overlay import DrawnOverlay, DrawnOverlayCfg
from vistac_sim.effects.exposure import Exposure, ExposureCfg
from vistac_sim.effects.jpeg import Jpeg, JpegCfg
from vistac_sim.effects.lighting import Lighting, LightingCfg, kelvin_rgb
from vistac_sim.effects.object_material import ObjectMaterial, ObjectMaterialCfg
from vistac_sim.effects.overlay_error import OverlayError, OverlayErrorCfg
from vistac_sim.effects.phone_camera import PhoneCamera, PhoneCameraCfg
from vistac_sim.effects.presets import resolve
from vistac_sim.effects.sensor_noise import SensorNoise, SensorNoiseCfg
from vistac_sim.effects.shadows import Shadows, ShadowsCfg
from vistac_sim.effects.table import Table, TableCfg
from vistac_sim.generate.config import GenerateCfg
from vistac_sim.generate.rigs import ObjectRig
from vistac_sim.mj import mujoco
from vistac_sim.render import textures
from vistac_sim.render.drawn import drawn_boxes, drawn_shapes
from vistac_sim.render.finish import apply_finish, motion_kernel
from vistac_sim.render.outlines import moved_capsules
from vistac_sim.render.shot import CameraPose, Finish, Shot
from vistac_sim.render.shot_render import GEOM, render_mask, render_shot, shot_boxes

FINGERS = ("index", "thumb")


@pytest.fixture(scope="module")
def photo():
    """The photo preset's config and two pressed scenes with its texture banks."""
    cfg = GenerateCfg.from_preset("photo")
    scenes = [pressed_scene(cfg, k) for k in (0, 2)]
    yield cfg, scenes
    for s in scenes:
        s.close()


def seg_of(scene: ObjectRig, view: Shot) -> np.ndarray:
    return render_shot(scene.view, scene.press.data, view, segmentation=True)


def geom_mask(scene: ObjectRig, seg: np.ndarray, name: str) -> np.ndarray:
    gid = mujoco.mj_name2id(scene.model, mujoco.mjtObj.mjOBJ_GEOM, name)
    return (seg[..., 1] == GEOM) & (seg[..., 0] == gid)


def pixel_box(mask: np.ndarray) -> np.ndarray:
    ys, xs = np.nonzero(mask)
    return np.array([xs.min(), ys.min(), xs.max() + 1 - xs.min(), ys.max() + 1 - ys.min()])


# ------------------------------------------------------------------ textures and materials
def test_texture_bank_is_fixed_and_holds_every_kind():
    obj, table = textures.bank("object"), textures.bank("table")
    assert set(obj) == set(textures.OBJECT_KINDS) and set(table) == set(textures.TABLE_KINDS)
    for bank in (obj, table):
        for kind, texs in bank.items():
            assert texs, kind
            for t in texs:
                assert t.shape == (textures.SIZE, textures.SIZE, 3) and t.dtype == np.uint8
                assert t.std() > 2, kind  # a pattern, not a flat colour
    assert len(obj["photo"]) == len(BANK_PHOTOS["object"])
    # a pure function of (kind, variant): the same in every process
    textures.procedural.cache_clear()
    again = textures.bank("object")
    np.testing.assert_array_equal(again["wood"][1], obj["wood"][1])


def test_user_textures_join_the_photographs(tmp_path):
    for i in range(2):
        img = np.full((40, 60, 3), 50 * (i + 1), np.uint8)
        cv2.imwrite(str(tmp_path / f"t{i}.png"), img)
    bank = textures.bank("table", str(tmp_path))
    assert len(bank["photo"]) == len(BANK_PHOTOS["table"]) + 2
    assert bank["photo"][-1].mean() == pytest.approx(100, abs=1)
    (tmp_path / "empty").mkdir()
    with pytest.raises(UserError, match="no readable image"):
        textures.user_textures(str(tmp_path / "empty"))
    with pytest.raises(UserError, match="no such folder"):
        textures.user_textures(str(tmp_path / "nowhere"))


def test_textures_only_in_scenes_that_ask(photo):
    cfg, scenes = photo
    clean = pressed_scene(GenerateCfg(), 0)
    try:
        assert clean.model.ntex == 0 and clean.view.texture_ids == {}
    finally:
        clean.close()
    ids = scenes[0].view.texture_ids
    assert set(ids) == {"object", "table"}
    assert set(ids["object"]) == set(textures.OBJECT_KINDS)


def test_object_material_textures_the_object_only(photo):
    cfg, scenes = photo
    scene = scenes[0]
    d = scene.press.data
    plain = ObjectMaterial(ObjectMaterialCfg(plain=1.0, saturation=(0, 0), value=(1, 1),
                                             specular=(0, 0)))
    striped = ObjectMaterial(ObjectMaterialCfg(kinds=("stripes",), plain=0.0,
                                               saturation=(0, 0), value=(1, 1),
                                               specular=(0, 0)))
    v0 = plain(Shot.of(cfg.render), np.random.default_rng(0))
    v1 = striped(Shot.of(cfg.render), np.random.default_rng(0))
    assert v0.object_look.kind == "" and v1.object_look.kind == "stripes"
    obj = geom_mask(scene, seg_of(scene, v0), "object_visual")
    a, b = render_shot(scene.view, d, v0), render_shot(scene.view, d, v1)
    np.testing.assert_array_equal(a[~obj], b[~obj])  # table and fingers untouched
    assert b[obj].astype(float).std(0).mean() > a[obj].astype(float).std(0).mean() + 10
    tinted = dataclasses.replace(v1, object_look=dataclasses.replace(v1.object_look,
                                                                     rgb=(1.0, 0.2, 0.2)))
    c = render_shot(scene.view, d, tinted)[obj].mean(0)
    assert c[0] > 2 * c[1] and c[0] > 2 * c[2]  # the tint multiplies the texture


def test_table_texture_kinds_and_tint(photo):
    cfg, scenes = photo
    scene = scenes[1]
    d = scene.press.data
    view = Table(TableCfg(kinds=("wood",), rgb_std=0.0, texture=0.0))(
        Shot.of(cfg.render), np.random.default_rng(3))
    assert view.texture is None and view.table_look.kind == "wood"
    assert view.table_rgb == (1.0, 1.0, 1.0)
    table = geom_mask(scene, seg_of(scene, view), "table")
    rgb = render_shot(scene.view, d, view)
    clean = render_shot(scene.view, d, Shot.of(cfg.render))
    assert clean[table].std(0).max() < 1.0
    assert rgb[table].astype(float).std(0).mean() > 8  # wood grain
    assert rgb[table][:, 0].mean() > rgb[table][:, 2].mean() + 20  # brown, not grey
    np.testing.assert_array_equal(rgb[~table], clean[~table])


# --------------------------------------------------------------------- light and shadows
def test_colour_temperature():
    warm, white, cool = kelvin_rgb(3000), kelvin_rgb(6600), kelvin_rgb(9000)
    assert warm[0] > warm[1] > warm[2] and cool[2] > cool[0]
    np.testing.assert_allclose(white, 1.0, atol=0.03)
    for rgb in (warm, cool):
        assert 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2] == pytest.approx(1.0)


def test_warm_light_colours_the_table(photo):
    cfg, scenes = photo
    scene = scenes[0]
    eff = Lighting(LightingCfg(elevation_deg=(90, 90), temperature_k=(3000, 3000)))
    view = eff(Shot.of(cfg.render), np.random.default_rng(0))
    assert view.light.rgb == kelvin_rgb(3000)
    table = geom_mask(scene, seg_of(scene, view), "table")
    rgb = render_shot(scene.view, scene.press.data, view)[table].mean(0)
    assert rgb[0] > rgb[2] + 15  # the grey table lit warm


def test_shadow_probability_and_softness():
    eff = Shadows(ShadowsCfg(probability=0.3, softness=0.02))
    views = [eff(Shot.of(GenerateCfg().render), np.random.default_rng(i)) for i in range(400)]
    assert np.mean([v.shadows for v in views]) == pytest.approx(0.3, abs=0.07)
    assert {v.light.softness for v in views} == {0.02}


# ------------------------------------------------------------------------ phone camera
def test_phone_camera_fills_the_frame_with_the_working_area():
    cfg = GenerateCfg()
    cam = CameraPose(fovy=float(np.radians(60)))
    view = dataclasses.replace(Shot.of(cfg.render), camera=cam)
    half = cfg.render.view_extent / 2
    np.testing.assert_allclose(view.project(np.array([[-half, half, 0], [half, -half, 0]])),
                               [[0, 0], [227, 227]], atol=1e-9)
    assert view.distance == pytest.approx(half / np.tan(np.radians(30)))
    # a point above the table is seen farther out (perspective), unlike orthographic
    up = view.project(np.array([half / 2, 0, 0.03]))
    assert up[0] > 227 * 0.75 + 1
    eff = PhoneCamera(PhoneCameraCfg())
    for i in range(50):
        v = eff(Shot.of(cfg.render), np.random.default_rng(i))
        assert np.degrees(v.camera.tilt) <= 5.0 + 1e-9 and abs(np.degrees(v.camera.roll)) <= 5
        assert 50 <= np.degrees(v.camera.fovy) <= 70


def test_boxes_under_the_phone_camera_match_the_rendered_fingers(photo):
    cfg, scenes = photo
    eff = PhoneCamera(PhoneCameraCfg(tilt_deg=5.0, roll_deg=20.0))
    moved = OverlayError(OverlayErrorCfg(offset_std=0.003, rotation_std_deg=8.0))
    for i, scene in enumerate(scenes):
        for k in range(3):
            view = eff(Shot.of(cfg.render), np.random.default_rng(10 * i + k))
            if k == 2:  # rendered fingers moved off the true ones: drawn over the scene
                view = moved(view, np.random.default_rng(k))
            obj = mujoco.mj_name2id(scene.model, mujoco.mjtObj.mjOBJ_GEOM, "object_visual")
            group = int(scene.model.geom_group[obj])
            scene.model.geom_group[obj] = 3  # a tilted view lets the object hide a sliver
            try:
                seg = seg_of(scene, view)
            finally:
                scene.model.geom_group[obj] = group
            boxes = shot_boxes(scene.model, scene.press.data, scene.ids, view)
            for j, f in enumerate(FINGERS):
                pix = (seg[..., 1] == GEOM) & np.isin(seg[..., 0],
                                                      [scene.ids.pad[f], scene.ids.shaft[f]])
                np.testing.assert_allclose(boxes[j], pixel_box(pix), atol=1.5)


# ------------------------------------------------------------------------- the finish
def test_exposure_and_white_balance_gain():
    view = Exposure(ExposureCfg(ev=(1.0, 1.0), balance=0.0))(Shot.of(GenerateCfg().render),
                                                             np.random.default_rng(0))
    assert view.finish.gain == (2.0, 2.0, 2.0)
    img = np.full((32, 32, 3), 60, np.uint8)
    np.testing.assert_array_equal(apply_finish(img, view.finish), 120)
    wb = Exposure(ExposureCfg(ev=(0, 0), balance=0.2))(Shot.of(GenerateCfg().render),
                                                      np.random.default_rng(1))
    assert wb.finish.gain[1] == 1.0 and wb.finish.gain[0] != 1.0


def test_blur_softens_edges():
    img = np.zeros((64, 64, 3), np.uint8)
    img[:, 32:] = 200
    for fin in (Finish(defocus=1.0), Finish(motion=(5.0, 0.0))):
        out = apply_finish(img, fin).astype(int)
        assert 0 < out[10, 31, 0] < 200 and out[10, 0, 0] == 0 and out[10, 63, 0] == 200
    k = motion_kernel(4.0, 0.0)
    assert k.sum() == pytest.approx(1.0) and (k > 0).sum() >= 4
    v = Blur(BlurCfg(defocus_px=(0.0, 0.2), motion_px=(0.0, 0.5)))(
        Shot.of(GenerateCfg().render), np.random.default_rng(0))
    assert v.finish.defocus == 0.0 and v.finish.motion[0] == 0.0  # below the thresholds


def test_sensor_noise_std_follows_brightness_and_replays():
    view = SensorNoise(SensorNoiseCfg(read=(2.0, 2.0), shot=(0.1, 0.1)))(
        Shot.of(GenerateCfg().render), np.random.default_rng(0))
    for level in (40, 200):
        img = np.full((227, 227, 3), level, np.uint8)
        out = apply_finish(img, view.finish).astype(float)
        assert out.std() == pytest.approx(np.sqrt(4 + 0.1 * level), rel=0.1)
        assert out.mean() == pytest.approx(level, abs=0.2)
        np.testing.assert_array_equal(apply_finish(img, view.finish), out)


def test_jpeg_quality_range_and_artefacts():
    eff = Jpeg(JpegCfg(quality=(60, 62)))
    qs = {eff(Shot.of(GenerateCfg().render), np.random.default_rng(i)).finish.jpeg
          for i in range(40)}
    assert qs == {60, 61, 62}
    rng = np.random.default_rng(0)
    img = cv2.resize(rng.integers(0, 255, (16, 16, 3), dtype=np.uint8), (64, 64))
    out = apply_finish(img, Finish(jpeg=30)).astype(int)
    assert 0 < np.abs(out - img).mean() < 20


def test_jpeg_round_trip_keeps_the_channel_order():
    """The finish swaps channels with OpenCV: the same pixels as a numpy-reversed round trip, and
    a red patch stays red (JPEG's chroma is computed on the right channels)."""
    img = np.zeros((48, 48, 3), np.uint8)
    img[8:40, 8:40] = (230, 40, 10)
    out = apply_finish(img, Finish(jpeg=60))
    ok, buf = cv2.imencode(".jpg", img[..., ::-1], [cv2.IMWRITE_JPEG_QUALITY, 60])
    np.testing.assert_array_equal(out, cv2.imdecode(buf, cv2.IMREAD_COLOR)[..., ::-1])
    r, g, b = out[24, 24].astype(int)
    assert r > 200 and b < 40 and out.flags["C_CONTIGUOUS"]


# -------------------------------------------------------------------- drawn fingers
def test_drawn_fingers_replace_the_rendered_ones_and_boxes_hold_them(photo):
    cfg, scenes = photo
    scene = scenes[0]
    d = scene.press.data
    for i, cfg_d in enumerate([DrawnOverlayCfg(outline=1.0, antialias=0.0, tapered=0.0),
                               DrawnOverlayCfg(outline=0.0, antialias=1.0, tapered=1.0)]):
        view = PhoneCamera(PhoneCameraCfg())(Shot.of(cfg.render), np.random.default_rng(i))
        view = DrawnOverlay(cfg_d)(view, np.random.default_rng(i))
        seg = seg_of(scene, view)
        for f in FINGERS:  # the rendered fingers are hidden
            assert not np.isin(seg[..., 0][seg[..., 1] == GEOM],
                               [scene.ids.pad[f], scene.ids.shaft[f]]).any()
        shapes = drawn_shapes(moved_capsules(scene.model, d, scene.ids, view), view)
        boxes = drawn_boxes(shapes, view.image_size)
        mask = render_mask(scene.view, d, view)
        rgb = render_shot(scene.view, d, view)
        for j in range(len(FINGERS)):
            np.testing.assert_allclose(boxes[j], pixel_box(mask == 2 + j), atol=1.5)
            colour = np.array(view.drawn.rgb[j]) * 255
            inside = np.all(np.abs(rgb.astype(float) - colour) < 2, axis=-1)
            assert inside.sum() > 50  # the fill colour is drawn
            assert (mask[inside] == 2 + j).mean() > 0.97


def test_drawn_width_and_taper_change_the_shape(photo):
    cfg, scenes = photo
    scene = scenes[1]
    d = scene.press.data
    base = DrawnOverlay(DrawnOverlayCfg(width=(1.0, 1.0), outline=0.0, tapered=0.0))(
        Shot.of(cfg.render), np.random.default_rng(0))

    def area(view) -> int:
        mask = render_mask(scene.view, d, view)
        return int((mask == 2).sum() + (mask == 3).sum())

    wide = dataclasses.replace(base, drawn=dataclasses.replace(base.drawn, width=(1.2, 1.2)))
    tapered = dataclasses.replace(base, drawn=dataclasses.replace(base.drawn, taper=0.5))
    a0 = area(base)
    assert area(wide) > 1.1 * a0 and area(tapered) < 0.95 * a0


# ------------------------------------------------------------------ the preset and masks
def test_disabled_photo_effects_are_never_built_nor_called(monkeypatch):
    def forbidden(*a, **k):
        raise AssertionError("a disabled effect was touched")

    for cls in (ObjectMaterial, PhoneCamera, Exposure, Blur, SensorNoise, Jpeg, DrawnOverlay):
        monkeypatch.setattr(cls, "__init__", forbidden)
        monkeypatch.setattr(cls, "__call__", forbidden)
    assert build_pipeline(EffectsCfg()).image == []
    assert build_pipeline(resolve("harsh")[0]).image  # the older presets do not use them
    with pytest.raises(AssertionError):
        build_pipeline(resolve("photo")[0])


def test_photo_keeps_labels_and_writes_masks(tmp_path):
    args = ["--n", "4", "--seed", "5", "--workers", "1", "--no-progress", "--n-objects", "2",
            "--noise", "0.05"]
    assert main(["generate", "--out", str(tmp_path / "clean"), "--masks", *args]) == 0
    assert main(["generate", "--out", str(tmp_path / "photo"), "--preset", "photo", "--masks",
                 *args]) == 0
    presses = [(tmp_path / x / "presses.parquet").read_bytes() for x in ("clean", "photo")]
    assert presses[0] == presses[1]  # the same labels, byte for byte
    ca, cb = (pd.read_parquet(tmp_path / x / "configs.parquet") for x in ("clean", "photo"))
    for col in ("force_clean_index_z", "normal_thumb_y", "tip_index_x", "object_yaw"):
        np.testing.assert_array_equal(ca[col], cb[col])
    assert (cb["camera_fovy_deg"] > 0).all() and cb["jpeg_quality"].between(60, 95).all()
    manifest = json.loads((tmp_path / "photo" / "manifest.json").read_text())
    assert manifest["masks"] == {"folder": "masks",
                                 "values": {"table": 0, "object": 1, "index": 2, "thumb": 3}}
    assert manifest["config"]["render"]["masks"] is True
    for name, configs in (("clean", ca), ("photo", cb)):
        dataset = open_tables(tmp_path / name)
        for i, row in configs.iterrows():
            img = cv2.imread(str(dataset.image_path(i)))
            mask = cv2.imread(str(dataset.mask_path(i)), cv2.IMREAD_UNCHANGED)
            assert mask.shape == img.shape[:2] and mask.dtype == np.uint8
            assert set(np.unique(mask)) <= {0, 1, 2, 3} and (mask == 1).any()
            for j, f in enumerate(FINGERS):
                if (mask == 2 + j).any():
                    box = row[[f"bbox_{f}_{c}" for c in "xywh"]].to_numpy(float)
                    np.testing.assert_allclose(box, pixel_box(mask == 2 + j), atol=1.5)
