"""Drawing a `Shot`: what the camera sees differs from the clean top view, the physics does not.

Everything a view changes is applied to MuJoCo's *visual scene* (`MjvScene`) between
``update_scene`` and ``render``, so the model and the physics state are never touched and nothing
needs restoring:

- overlay error: the pad and shaft geoms of each drawn finger are moved and turned about the
  fingertip (the drawn finger misses where the finger really was) and, like the study's fingers
  painted into the photograph, drawn on top of everything without a shadow (moved towards the
  camera along its view axis, which leaves their pixels where they are);
- camera jitter: the GL camera is shifted, scaled, tilted off vertical and rolled;
- lighting: the headlight keeps only its ambient part and a directional key light is added;
- shadows: that key light casts shadows (needs a shadow map, created with the renderer only for
  scenes that ask for shadows: `vistac_sim.effects.shadows.shadow_map_size`);
- table: the table's colour, and a brightness pattern multiplied onto the table's pixels (found
  with a segmentation render of the same scene), or a texture of the table bank;
- object material: the object's texture (of the object bank), tint and shine;
- phone camera: a perspective GL camera (the drawn fingers are then moved towards the camera
  along the rays through it, and shrunk alike, which again leaves their pixels in place);
- after the render, in image space: the camera's finish (`vistac_sim.render.finish`) and the
  fingers drawn by hand (`vistac_sim.render.drawn`; the rendered fingers are then hidden).

Without image effects `vistac_sim.generate.configuration` keeps the plain render path.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import cv2
import numpy as np

from vistac.dataset import FINGERS
from vistac.dataset.schema import MASK_VALUES
from vistac.projection import displace, rotz
from vistac_sim.hand.ids import ModelIds
from vistac_sim.mj import mujoco
from vistac_sim.render import materials
from vistac_sim.render.boxes import boxes_from_outlines
from vistac_sim.render.config import RenderCfg
from vistac_sim.render.drawn import draw_fingers, drawn_boxes, drawn_shapes, fill_mask
from vistac_sim.render.finish import apply_finish
from vistac_sim.render.outlines import many_finger_shapes, moved_capsules, polygons_box
from vistac_sim.render.shot import Shot, TableTexture
from vistac_sim.render.topview import TopView, finger_capsules

if TYPE_CHECKING:
    from vistac_sim.effects.registry import Pipeline

OVERLAY_LIFT = 0.2  # m a drawn finger is moved towards the camera (in front of any object)
PERSPECTIVE_LIFT = 0.5  # a drawn finger's distance from a perspective camera is scaled by this
HIDDEN_Z = -10.0  # m, where a hidden geom goes (under the opaque table)
GEOM = int(mujoco.mjtObj.mjOBJ_GEOM)  # a plain int: comparing arrays with the enum is slow


def render_with_effects(top: TopView, data: mujoco.MjData, pipeline: Pipeline, cfg: RenderCfg,
                        rng: np.random.Generator, masks: bool = False
                        ) -> tuple[np.ndarray, np.ndarray, dict, np.ndarray | None]:
    """Run the image effects on the clean shot, then render it.

    Returns:
        (RGB image, (2, 4) boxes of the drawn fingers as the image shows them, the view's
        configuration-table columns, the mask (`render_mask`) or None).
    """
    shot = pipeline.apply_image(Shot.of(cfg), rng)
    shapes = drawn_shapes(moved_capsules(top.model, data, top.ids, shot), shot) \
        if shot.drawn is not None else None
    rgb = render_shot(top, data, shot, shapes=shapes)
    boxes = drawn_boxes(shapes, shot.image_size) if shapes is not None \
        else shot_boxes(top.model, data, top.ids, shot)
    mask = render_mask(top, data, shot, shapes) if masks else None
    return rgb, boxes, shot.columns(), mask


def render_shot(top: TopView, data: mujoco.MjData, shot: Shot, segmentation: bool = False,
                shapes: list | None = None) -> np.ndarray:
    """RGB image (H, W, 3) uint8 of the current state as `shot` sees it (or the segmentation).

    `shapes` are the drawn fingers' polygons when the caller has them (`drawn_shapes`).

    Raises:
        ValueError: the view asks for shadows from a renderer made without a shadow map.
    """
    if shot.shadows and top.model.vis.quality.shadowsize <= 0:
        raise ValueError("shadows need a renderer made with a shadow map (shadow_map_size)")
    r = top.renderer
    r.update_scene(data, camera=top.ids.camera, scene_option=top.option)
    table = _apply_shot(r.scene, top, data, shot)
    if segmentation:
        return _segmentation(r)
    rgb = r.render()
    if shot.texture is not None:
        seg = _segmentation(r)
        mask = (seg[..., 1] == GEOM) & (seg[..., 0] == table)
        gain = texture_pattern(shot.texture, shot.image_size, shot.px_per_m)
        shaded = np.clip(rgb * np.where(mask, gain, 1.0)[..., None], 0, 255)
        rgb = np.rint(shaded).astype(np.uint8)
    if shot.finish is not None:
        rgb = apply_finish(rgb, shot.finish)
    if shot.drawn is not None:
        if shapes is None:
            shapes = drawn_shapes(moved_capsules(top.model, data, top.ids, shot), shot)
        rgb = draw_fingers(rgb, shapes, shot.drawn)
    return rgb


def render_mask(top: TopView, data: mujoco.MjData, shot: Shot | None = None,
                shapes: list | None = None) -> np.ndarray:
    """(H, W) uint8 labels of what the image shows: 0 table (and anything else), 1 object,
    2 index finger, 3 thumb (the drawn finger where the view draws them, else the rendered
    one). `shot` None is the plain top view."""
    if shot is None:
        seg = top.render(data, segmentation=True)
    else:
        seg = render_shot(top, data, shot, segmentation=True)
    ids = top.ids
    mask = np.zeros(seg.shape[:2], np.uint8)
    geom = seg[..., 1] == GEOM
    obj = mujoco.mj_name2id(top.model, mujoco.mjtObj.mjOBJ_GEOM, "object_visual")
    mask[geom & (seg[..., 0] == obj)] = MASK_VALUES["object"]
    if shot is not None and shot.drawn is not None:
        if shapes is None:
            shapes = drawn_shapes(moved_capsules(top.model, data, ids, shot), shot)
        return fill_mask(mask, shapes)
    for f in FINGERS:
        mask[geom & np.isin(seg[..., 0], [ids.pad[f], ids.shaft[f]])] = MASK_VALUES[f]
    return mask


def _segmentation(renderer: mujoco.Renderer) -> np.ndarray:
    renderer.enable_segmentation_rendering()
    try:
        return renderer.render()
    finally:
        renderer.disable_segmentation_rendering()


def _apply_shot(scn: mujoco.MjvScene, top: TopView, data: mujoco.MjData, shot: Shot) -> int:
    """Change the visual scene as `shot` asks; returns the table's geom id."""
    model, ids = top.model, top.ids
    table = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "table")
    banks = top.texture_ids  # empty unless the scene has textures
    obj = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "object_visual") \
        if "object" in banks else -2
    pos, right, up, fwd = shot.frame()
    lift = -OVERLAY_LIFT * fwd  # towards the camera: same pixels, in front of everything
    moves = {}
    fingers = {g for f in FINGERS for g in (ids.pad[f], ids.shaft[f])}
    if shot.drawn is None:
        for f, overlay in zip(FINGERS, shot.overlay, strict=True):
            if any(overlay):
                pivot = data.site_xpos[ids.site[f]].copy()
                for g in (ids.pad[f], ids.shaft[f]):
                    moves[g] = (pivot, overlay)
    for i in range(scn.ngeom):
        g = scn.geoms[i]
        if g.objtype != GEOM:
            continue
        if g.objid in moves:  # a drawn finger: painted over the scene, without a shadow
            pivot, overlay = moves[g.objid]
            moved = displace(np.asarray(g.pos, float), pivot, overlay)
            if shot.perspective:  # along the rays through the camera, shrunk alike
                g.pos[:] = pos + PERSPECTIVE_LIFT * (moved - pos)
                g.size[:] = PERSPECTIVE_LIFT * np.asarray(g.size, float)
            else:
                g.pos[:] = moved + lift
            g.mat[:] = rotz(overlay[2]) @ np.asarray(g.mat, float)
            g.castshadow = 0
        elif shot.drawn is not None and g.objid in fingers:  # drawn in 2D later: hide
            g.pos[2] = HIDDEN_Z
            g.castshadow = 0
        elif g.objid == table:
            g.rgba[:3] = shot.table_rgb
            if "table" in banks:
                _dress(g, shot.table_look, banks["table"], uniform=True)
        elif g.objid == obj:
            if shot.object_look is not None:
                g.rgba[:3] = shot.object_look.rgb
            _dress(g, shot.object_look, banks["object"], uniform=False)
    half = shot.image_size / shot.px_per_m / 2
    for cam in scn.camera:  # both eyes at the same place: a mono view
        cam.pos[:], cam.forward[:], cam.up[:] = pos, fwd, up
        if shot.perspective:
            near = 0.05 * shot.distance
            cam.orthographic = 0
            cam.frustum_near, cam.frustum_far = near, 10.0 * shot.distance
            top_ = near * float(np.tan(shot.camera.fovy / 2))
            cam.frustum_center, cam.frustum_top, cam.frustum_bottom = 0.0, top_, -top_
        else:
            cam.frustum_center, cam.frustum_top, cam.frustum_bottom = 0.0, half, -half
    if shot.light is not None:
        _add_key_light(scn, shot)
    return table


def _dress(g: mujoco.MjvGeom, look, texture_ids: dict[str, list[int]], uniform: bool) -> None:
    """A surface's texture, its repeats per metre and its shine on a visual-scene geom (none
    for no look or a plain one: without its material the geom is not textured)."""
    if look is None or not look.kind:
        g.matid = g.texid = -1
        if look is not None:
            g.specular, g.shininess = look.specular, look.shininess
        return
    g.texid = materials.pick(texture_ids, look.kind, look.pick)
    g.texrepeat[:] = (look.repeat, look.repeat)
    g.texuniform = int(uniform)
    g.specular, g.shininess = look.specular, look.shininess


def _add_key_light(scn: mujoco.MjvScene, shot: Shot) -> None:
    light = shot.light
    for i in range(scn.nlight):
        if scn.lights[i].headlight:
            h = scn.lights[i]
            h.ambient[:], h.diffuse[:], h.specular[:] = light.ambient, 0.0, 0.0
    if scn.nlight >= len(scn.lights):
        raise RuntimeError("no room for the key light in the visual scene")
    key = scn.lights[scn.nlight]
    scn.nlight += 1
    key.type = mujoco.mjtLightType.mjLIGHT_DIRECTIONAL
    key.headlight = 0
    key.dir[:] = light.direction
    key.pos[:] = (*shot.camera.center, 0.0)  # directional: centre of the shadow map
    rgb = np.asarray(light.rgb, float)
    key.ambient[:], key.diffuse[:], key.specular[:] = 0.0, light.diffuse * rgb, \
        light.specular * rgb
    key.attenuation[:] = (1.0, 0.0, 0.0)
    key.castshadow = int(shot.shadows)
    key.bulbradius = light.softness


def texture_pattern(texture: TableTexture, size: int, px_per_m: float) -> np.ndarray:
    """(size, size) brightness gain 1 + strength * (unit-std fractal noise), at least 0."""
    rng = np.random.default_rng(texture.seed)
    noise = np.zeros((size, size))
    for octave in range(max(1, texture.octaves)):
        cell = max(texture.scale * px_per_m / 2**octave, 1.0)
        n = int(np.ceil(size / cell)) + 3
        grid = rng.standard_normal((n, n)).astype(np.float32)
        up = cv2.resize(grid, (int(round(n * cell)),) * 2, interpolation=cv2.INTER_CUBIC)
        noise += up[:size, :size] * 0.5**octave
    noise = (noise - noise.mean()) / max(noise.std(), 1e-12)
    return np.maximum(1.0 + texture.strength * noise, 0.0)


def shot_boxes(model: mujoco.MjModel, data: mujoco.MjData, ids: ModelIds,
               shot: Shot) -> np.ndarray:
    """(2, 4) pixel boxes (x, y, w, h; top-left origin) of the visible part of each finger as
    `shot` draws it.

    As `topview.finger_boxes` (which it equals for the clean shot), for any camera pose and
    overlay error: each capsule is moved by the overlay, its end points are projected, and the
    segment between them widened by the radius in pixels is its outline (an orthographic view
    draws a sphere as a circle of the same radius); the box bounds the union of a finger's
    outlines clipped to the image. Under a tilted camera the top of a tall object may hide a
    sliver of a (not overlaid) finger; the box still holds the finger's whole outline. A
    perspective view draws the capsules as hulls of ellipses: their box comes from polygons
    circumscribed about them (`vistac_sim.render.outlines`).
    """
    if shot.perspective:
        shapes = many_finger_shapes([(caps, 1.0, 0.0, 1.0) for caps in
                                     moved_capsules(model, data, ids, shot)], shot)
        return np.stack([polygons_box(polys, shot.image_size) for polys in shapes])
    s = shot.px_per_m
    caps_px = []
    for k, (f, caps) in enumerate(zip(FINGERS, finger_capsules(model, data, ids), strict=True)):
        pivot = data.site_xpos[ids.site[f]]
        moved = []
        for a, b, r in caps:
            p0, p1 = shot.project(displace(np.array([a, b]), pivot, shot.overlay[k]))
            moved.append((p0, p1, r * s))
        caps_px.append(moved)
    return boxes_from_outlines(caps_px, shot.image_size)
