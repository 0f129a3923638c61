"""Image-stage effects: each one's signature, the render hook, and that a disabled one costs
nothing (never built nor called)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest
from pressed_scenes import pressed_scene

from vistac.config import apply
from vistac_sim.effects.camera_jitter import CameraJitter, CameraJitterCfg
from vistac_sim.effects.lighting import Lighting, LightingCfg
from vistac_sim.effects.overlay_error import OverlayError, OverlayErrorCfg
from vistac_sim.effects.registry import build_pipeline
from vistac_sim.effects.shadows import Shadows, ShadowsCfg, shadow_map_size
from vistac_sim.effects.table import Table, TableCfg
from vistac_sim.generate.config import GenerateCfg
from vistac_sim.generate.rigs import ObjectRig
from vistac_sim.mj import mujoco
from vistac_sim.render import shot_render
from vistac_sim.render.shot import CameraPose, Shot
from vistac_sim.render.shot_render import GEOM, render_shot, shot_boxes
from vistac_sim.render.topview import finger_boxes

FINGERS = ("index", "thumb")


@pytest.fixture(scope="module")
def scenes():
    cfg = GenerateCfg()
    out = [pressed_scene(cfg, i) for i in range(3)]
    yield cfg, out
    for s in out:
        s.close()


def seg_boxes(scene: ObjectRig, seg: np.ndarray) -> np.ndarray:
    """(2, 4) pixel boxes of each finger's pixels in a segmentation image."""
    out = np.zeros((2, 4))
    for k, f in enumerate(FINGERS):
        mask = (seg[..., 1] == GEOM) & np.isin(
            seg[..., 0], [scene.ids.pad[f], scene.ids.shaft[f]])
        ys, xs = np.nonzero(mask)
        out[k] = [xs.min(), ys.min(), xs.max() + 1 - xs.min(), ys.max() + 1 - ys.min()]
    return out


def table_mask(scene: ObjectRig, seg: np.ndarray) -> np.ndarray:
    table = mujoco.mj_name2id(scene.model, mujoco.mjtObj.mjOBJ_GEOM, "table")
    return (seg[..., 1] == GEOM) & (seg[..., 0] == table)


# ------------------------------------------------------------------------- the clean view
def test_clean_view_renders_and_boxes_as_the_plain_path(scenes):
    cfg, ss = scenes
    view = Shot.of(cfg.render)
    assert view.px_per_m == pytest.approx(cfg.render.image_size / cfg.render.view_extent)
    for scene in ss:
        d = scene.press.data
        np.testing.assert_array_equal(render_shot(scene.view, d, view), scene.view.render(d))
        np.testing.assert_allclose(shot_boxes(scene.model, d, scene.ids, view),
                                   finger_boxes(scene.model, d, scene.ids, cfg.render),
                                   atol=1e-9)
        cols = view.columns()
        assert (cols["camera_x"], cols["camera_y"]) == (0.0, 0.0)
        assert cols["px_per_m"] == pytest.approx(cfg.render.image_size / cfg.render.view_extent)


# ------------------------------------------------------------------------ overlay error
def test_overlay_error_moves_drawn_finger_and_box_by_the_offset(scenes):
    cfg, ss = scenes
    scene = ss[0]
    d = scene.press.data
    qpos, xpos = d.qpos.copy(), d.geom_xpos.copy()
    effect = OverlayError(OverlayErrorCfg(offset_std=0.0, rotation_std_deg=0.0,
                                          offset=(0.004, -0.003)))
    view = effect(Shot.of(cfg.render), np.random.default_rng(0))
    s = view.px_per_m
    clean_seg = scene.view.render(d, segmentation=True)
    seg = render_shot(scene.view, d, view, segmentation=True)
    boxes = shot_boxes(scene.model, d, scene.ids, view)
    clean = finger_boxes(scene.model, d, scene.ids, cfg.render)
    for k, f in enumerate(FINGERS):
        ids = [scene.ids.pad[f], scene.ids.shaft[f]]
        before = np.argwhere(np.isin(clean_seg[..., 0], ids)).mean(0)
        after = np.argwhere(np.isin(seg[..., 0], ids)).mean(0)
        inside = clean[k, 0] > 2 and clean[k, 1] > 2 and clean[k].sum() < 220
        if inside:  # a finger cut by the image border moves its visible centroid differently
            np.testing.assert_allclose(after - before, [0.003 * s, 0.004 * s], atol=0.6)
            np.testing.assert_allclose(boxes[k, :2] - clean[k, :2], [0.004 * s, 0.003 * s],
                                       atol=1e-6)
    np.testing.assert_allclose(boxes, seg_boxes(scene, seg), atol=1.5)
    # the physics state is untouched
    np.testing.assert_array_equal(d.qpos, qpos)
    np.testing.assert_array_equal(d.geom_xpos, xpos)


def test_overlay_rotation_boxes_match_segmentation(scenes):
    cfg, ss = scenes
    effect = OverlayError(OverlayErrorCfg(offset_std=0.002, rotation_std_deg=10.0,
                                          rotation_deg=15.0))
    for i, scene in enumerate(ss):
        view = effect(Shot.of(cfg.render), np.random.default_rng(i))
        seg = render_shot(scene.view, scene.press.data, view, segmentation=True)
        boxes = shot_boxes(scene.model, scene.press.data, scene.ids, view)
        np.testing.assert_allclose(boxes, seg_boxes(scene, seg), atol=1.5)


def test_overlay_error_changes_image_not_labels(tmp_path):
    from vistac_sim.generate.run import generate

    base = apply(GenerateCfg(n=4, seed=3), {"effects": {"noise": 0.05}})
    moved = dataclasses.replace(base, effects=dataclasses.replace(
        base.effects, overlay_error=OverlayErrorCfg(offset=(0.003, 0.0))))
    generate(base, tmp_path / "a", workers=1, progress=False)
    man = generate(moved, tmp_path / "b", workers=1, progress=False)
    assert [e["name"] for e in man["effects"]] == ["force_noise", "overlay_error"]
    pa, pb = (pd.read_parquet(tmp_path / x / "presses.parquet") for x in "ab")
    pd.testing.assert_frame_equal(pa, pb)  # labels identical, bit for bit
    ca, cb = (pd.read_parquet(tmp_path / x / "configs.parquet") for x in "ab")
    for col in ("force_clean_index_z", "normal_thumb_y", "tip_index_x"):
        np.testing.assert_array_equal(ca[col], cb[col])
    assert not np.allclose(ca["bbox_index_x"], cb["bbox_index_x"])
    assert np.allclose(cb["overlay_index_dx"] - 0.003, 0.0, atol=0.01)
    img_a = (tmp_path / "a" / "images" / "000000.png").read_bytes()
    assert img_a != (tmp_path / "b" / "images" / "000000.png").read_bytes()


# ------------------------------------------------------------------------ camera jitter
def test_camera_jitter_changes_projection_and_boxes_follow(scenes):
    cfg, ss = scenes
    effect = CameraJitter(CameraJitterCfg(shift_std=0.01, scale_std=0.1, tilt_std_deg=3.0,
                                          roll_std_deg=10.0))
    for i, scene in enumerate(ss):
        view = effect(Shot.of(cfg.render), np.random.default_rng(10 + i))
        cols = view.columns()
        assert cols["px_per_m"] != pytest.approx(cfg.render.image_size / cfg.render.view_extent)
        assert cols["camera_tilt_deg"] > 0 and cols["camera_roll_deg"] != 0
        # a tilted view lets a tall object's top hide a sliver of a finger: hide the object
        obj = mujoco.mj_name2id(scene.model, mujoco.mjtObj.mjOBJ_GEOM, "object_visual")
        group = int(scene.model.geom_group[obj])
        scene.model.geom_group[obj] = 3
        try:
            seg = render_shot(scene.view, scene.press.data, view, segmentation=True)
        finally:
            scene.model.geom_group[obj] = group
        boxes = shot_boxes(scene.model, scene.press.data, scene.ids, view)
        np.testing.assert_allclose(boxes, seg_boxes(scene, seg), atol=1.5)


def test_camera_center_and_scale_are_what_the_image_shows(scenes):
    cfg, ss = scenes
    scene = ss[0]
    cam = CameraPose(center=(0.01, -0.02), scale=1.25)
    view = dataclasses.replace(Shot.of(cfg.render), camera=cam)
    tip = scene.press.data.site_xpos[scene.ids.site["index"]]
    u, v = view.project(tip)
    s = cfg.render.image_size / cfg.render.view_extent * 1.25
    assert (u, v) == pytest.approx((113.5 + (tip[0] - 0.01) * s, 113.5 - (tip[1] + 0.02) * s))


# ---------------------------------------------------------------------- light and table
def test_lighting_direction_and_intensity_set_table_brightness(scenes):
    cfg, ss = scenes
    scene = ss[0]
    seg = scene.view.render(scene.press.data, segmentation=True)
    mask = table_mask(scene, seg)

    def table_level(el, diffuse, ambient):
        eff = Lighting(LightingCfg(elevation_deg=(el, el), azimuth_deg=(0, 0),
                                   intensity=(diffuse, diffuse), ambient=(ambient, ambient),
                                   specular=0.0))
        view = eff(Shot.of(cfg.render), np.random.default_rng(0))
        return np.median(render_shot(scene.view, scene.press.data, view)[mask], axis=0)

    top, low, dim = table_level(90, 0.5, 0.4), table_level(30, 0.5, 0.4), table_level(90, 0.2, 0.4)
    rgb = np.array(cfg.render.table_rgb) * 255
    np.testing.assert_allclose(top, rgb * 0.9, atol=3)  # ambient + diffuse * sin(90)
    np.testing.assert_allclose(low, rgb * 0.65, atol=3)  # ambient + diffuse * sin(30)
    np.testing.assert_allclose(dim, rgb * 0.6, atol=3)


def test_table_colour_and_texture_only_on_table_pixels(scenes):
    cfg, ss = scenes
    scene = ss[1]
    d = scene.press.data
    seg = scene.view.render(d, segmentation=True)
    mask = table_mask(scene, seg)
    clean = scene.view.render(d)
    plain = Table(TableCfg(rgb_std=0.0, texture=0.0))(Shot.of(cfg.render),
                                                      np.random.default_rng(0))
    assert plain.texture is None
    np.testing.assert_array_equal(render_shot(scene.view, d, plain), clean)
    view = Table(TableCfg(rgb_std=0.1, texture=0.08))(Shot.of(cfg.render),
                                                      np.random.default_rng(1))
    rgb = render_shot(scene.view, d, view)
    np.testing.assert_array_equal(rgb[~mask], clean[~mask])  # object and fingers untouched
    assert clean[mask].std(axis=0).max() < 1.0
    rel = rgb[mask].astype(float).std(axis=0) / rgb[mask].mean(axis=0)
    np.testing.assert_allclose(rel, 0.08, rtol=0.35)
    expect = np.array(view.table_rgb) / np.array(cfg.render.table_rgb)
    np.testing.assert_allclose(rgb[mask].mean(0) / clean[mask].mean(0), expect, rtol=0.03)
    again = render_shot(scene.view, d, view)
    np.testing.assert_array_equal(rgb, again)  # replayable from the stored parameters


# ----------------------------------------------------------------------------- shadows
def test_shadows_off_by_default_and_only_when_asked():
    cfg = GenerateCfg()
    assert shadow_map_size(cfg.effects) == 0
    assert build_pipeline(cfg.effects).image == []
    scene = pressed_scene(cfg, 2)
    try:
        assert scene.model.vis.quality.shadowsize == 0
        assert scene.view.renderer._mjr_context.shadowSize == 0
        view = Shadows(ShadowsCfg())(Shot.of(cfg.render), np.random.default_rng(0))
        with pytest.raises(ValueError, match="shadow map"):
            render_shot(scene.view, scene.press.data, view)
    finally:
        scene.close()


def test_shadows_darken_the_table_beside_the_object():
    cfg = apply(GenerateCfg(), {"effects": {"shadows": ShadowsCfg(elevation_deg=40.0)}})
    scene = pressed_scene(cfg, 2)
    try:
        assert scene.view.renderer._mjr_context.shadowSize == 2048
        d = scene.press.data
        mask = table_mask(scene, scene.view.render(d, segmentation=True))
        view = Shadows(ShadowsCfg(elevation_deg=40.0))(Shot.of(cfg.render),
                                                       np.random.default_rng(0))
        lit_only = dataclasses.replace(view, shadows=False)
        shaded = render_shot(scene.view, d, view)[mask].mean(axis=1)
        plain = render_shot(scene.view, d, lit_only)[mask].mean(axis=1)
        # the fixed key light keeps the lit table as bright as the headlight did
        assert np.median(plain) == pytest.approx(np.mean(cfg.render.table_rgb) * 255, abs=3)
        dark = shaded < 0.8 * plain
        assert dark.sum() > 100  # a shadow of the object and the fingers on the table
        assert np.all(shaded <= plain + 1)
    finally:
        scene.close()


# ----------------------------------------------------------------- pipeline and the hook
def test_disabled_image_effects_are_never_built_nor_called(monkeypatch, tmp_path):
    from vistac_sim.generate import configuration
    from vistac_sim.generate.run import generate

    def forbidden(*a, **k):
        raise AssertionError("a disabled image effect was touched")

    for cls in (OverlayError, CameraJitter, Lighting, Shadows, Table):
        monkeypatch.setattr(cls, "__init__", forbidden)
        monkeypatch.setattr(cls, "__call__", forbidden)
    monkeypatch.setattr(configuration, "render_with_effects", forbidden)
    monkeypatch.setattr(shot_render, "render_shot", forbidden)
    monkeypatch.setattr(shot_render, "Shot", forbidden)
    man = generate(GenerateCfg(n=3, seed=2), tmp_path / "d", workers=1, progress=False)
    assert man["effects"] == []
    cfg = pd.read_parquet(tmp_path / "d" / "configs.parquet")
    assert "camera_tilt_deg" not in cfg


def test_all_image_effects_in_the_manifest_and_columns(tmp_path):
    from vistac_sim.generate.run import generate

    cfg = apply(GenerateCfg(n=3, seed=5), {"effects": {
        "overlay_error": OverlayErrorCfg(), "camera_jitter": CameraJitterCfg(),
        "lighting": LightingCfg(), "shadows": ShadowsCfg(map_size=1024), "table": TableCfg()}})
    man = generate(cfg, tmp_path / "d", workers=1, progress=False)
    assert [x["name"] for x in man["effects"]] == ["overlay_error", "camera_jitter", "lighting",
                                                  "shadows", "table"]
    assert man["effects"][3]["params"]["map_size"] == 1024
    c = pd.read_parquet(tmp_path / "d" / "configs.parquet")
    for col in ("camera_tilt_deg", "overlay_thumb_rot_deg", "light_elevation_deg", "table_r",
                "table_texture"):
        assert np.isfinite(c[col]).all()
    assert c["shadows"].all()
    assert c["px_per_m"].nunique() == 3
