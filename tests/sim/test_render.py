"""Top view: exact finger boxes, finger colours, and the world-to-pixel mapping."""

import numpy as np
import pytest

from vistac_sim.generate.config import GenerateCfg
from vistac_sim.generate.rigs import ObjectRig, draw_grasp
from vistac_sim.objects.library import build_object, procedural_library
from vistac_sim.render.topview import finger_boxes, world_to_pixel


@pytest.fixture(scope="module")
def pressed_scenes():
    cfg = GenerateCfg()
    out = []
    for spec in procedural_library(cfg.objects, 3)[:4]:
        scene = ObjectRig(build_object(spec, cfg.hand.height), cfg)
        grasp = draw_grasp(scene, np.random.default_rng(1), cfg)[0]
        out.append((scene, grasp, scene.view.render(scene.press.data),
                    scene.view.render(scene.press.data, segmentation=True)))
    yield cfg, out
    for scene, *_ in out:
        scene.close()


def test_boxes_match_segmentation(pressed_scenes):
    cfg, scenes = pressed_scenes
    for scene, _, _, seg in scenes:
        boxes = finger_boxes(scene.model, scene.press.data, scene.ids, cfg.render)
        for k, f in enumerate(("index", "thumb")):
            mask = np.isin(seg[..., 0], [scene.ids.pad[f], scene.ids.shaft[f]])
            ys, xs = np.nonzero(mask)
            seg_box = [xs.min(), ys.min(), xs.max() + 1 - xs.min(), ys.max() + 1 - ys.min()]
            np.testing.assert_allclose(boxes[k], seg_box, atol=1.5)


def test_shared_context_renderer_draws_what_mujoco_renderer_draws(pressed_scenes):
    """One GL context for all scenes, used in turns, gives MuJoCo's own renderer's pixels."""
    from vistac_sim.mj import mujoco

    cfg, scenes = pressed_scenes
    size = cfg.render.image_size
    for scene, _, rgb, seg in scenes[::-1]:  # other scenes' contexts were made after this one's
        with mujoco.Renderer(scene.model, size, size) as ref:
            ref.update_scene(scene.press.data, camera=scene.ids.camera,
                             scene_option=scene.view.option)
            np.testing.assert_array_equal(scene.view.render(scene.press.data), ref.render())
            ref.enable_segmentation_rendering()
            np.testing.assert_array_equal(seg, ref.render())
        np.testing.assert_array_equal(scene.view.render(scene.press.data), rgb)


def test_fingers_are_drawn_green_and_red(pressed_scenes):
    cfg, scenes = pressed_scenes
    for scene, _, rgb, seg in scenes:
        assert rgb.shape == (cfg.render.image_size, cfg.render.image_size, 3)
        index = np.isin(seg[..., 0], [scene.ids.pad["index"], scene.ids.shaft["index"]])
        thumb = np.isin(seg[..., 0], [scene.ids.pad["thumb"], scene.ids.shaft["thumb"]])
        np.testing.assert_array_equal(np.median(rgb[index], axis=0), [0, 255, 0])
        np.testing.assert_array_equal(np.median(rgb[thumb], axis=0), [255, 0, 0])


def test_tip_lands_where_world_to_pixel_says(pressed_scenes):
    cfg, scenes = pressed_scenes
    for scene, _, _, seg in scenes:
        tip = scene.press.data.xpos[scene.model.geom_bodyid[scene.ids.pad["index"]]][:2]
        u, v = world_to_pixel(tip, cfg.render).astype(int)
        if 0 <= u < cfg.render.image_size and 0 <= v < cfg.render.image_size:
            assert seg[v, u, 0] == scene.ids.pad["index"]


def test_png_encoding_round_trips_exactly():
    import cv2

    from vistac_sim.render.png import encode_png

    rgb = np.random.default_rng(0).integers(0, 256, (31, 17, 3), dtype=np.uint8)
    back = cv2.imdecode(np.frombuffer(encode_png(rgb), np.uint8), cv2.IMREAD_UNCHANGED)
    np.testing.assert_array_equal(back[:, :, ::-1], rgb)
    assert encode_png(rgb) == encode_png(rgb.copy())


@pytest.mark.parametrize("shape", [(31, 17, 3), (23, 40)])
def test_grainy_png_encoding_round_trips_exactly_through_imread(tmp_path, shape):
    import cv2

    from vistac_sim.render.png import encode_png

    rng = np.random.default_rng(1)
    img = np.clip(rng.normal(128, 60, shape), 0, 255).astype(np.uint8)  # wraps when filtered
    grainy = encode_png(img, grainy=True)
    assert grainy != encode_png(img)  # a different encoding ...
    path = tmp_path / "grainy.png"
    path.write_bytes(grainy)
    back = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    np.testing.assert_array_equal(back[..., ::-1] if img.ndim == 3 else back, img)  # same pixels
    assert grainy == encode_png(img.copy(), grainy=True)


def test_grainy_png_encoding_is_chosen_for_photo_frames_only():
    from vistac_sim.generate.config import GenerateCfg
    from vistac_sim.generate.configuration import grainy_frames

    assert grainy_frames(GenerateCfg.from_preset("photo"))
    assert not any(grainy_frames(GenerateCfg.from_preset(p)) for p in ("clean", "lab", "harsh"))


def test_clipped_box_matches_shapely():
    import shapely
    from shapely.geometry import LineString

    from vistac_sim.render.boxes import clipped_points

    rng = np.random.default_rng(0)
    for _ in range(300):
        p0, p1 = rng.uniform(-60, 290, 2), rng.uniform(-60, 290, 2)
        if rng.random() < 0.1:
            p1 = p0.copy()  # a disc
        r = rng.uniform(1, 40)
        ref = LineString([p0, p1]).buffer(r, quad_segs=256).intersection(
            shapely.box(0, 0, 227, 227))
        pts = np.array(clipped_points(p0, p1, r, 227)).reshape(-1, 2)
        if ref.is_empty or ref.area < 1e-6:
            assert len(pts) == 0 or np.ptp(pts, axis=0).min() < 1e-3
            continue
        np.testing.assert_allclose([*pts.min(0), *pts.max(0)], ref.bounds, atol=2e-3)
