"""One grasp configuration end to end: grasp, press(es), effects, labels, render, table rows.

`make_configuration` turns a configuration id into its table rows and PNG, drawing all randomness
from generators derived from (seed, config_id), so the result does not depend on which worker
runs it or in which order.
"""

from __future__ import annotations

import json
from collections import Counter
from dataclasses import dataclass

import numpy as np

from vistac.dataset import FINGERS, press_rows, unit_labels
from vistac.dataset.schema import (
    box_columns,
    clean_force_columns,
    failed_objects_cell,
    normal_columns,
    redraw_cell,
)
from vistac_sim.effects.registry import Pipeline
from vistac_sim.generate.config import GenerateCfg
from vistac_sim.generate.rigs import NoValidGrasp, ObjectRig, RigCache, draw_grasp, solve
from vistac_sim.hand.grasp import Grasp
from vistac_sim.objects.library import BuiltObject
from vistac_sim.objects.specs import object_index
from vistac_sim.physics.checks import RejectedSample
from vistac_sim.physics.press import PressResult
from vistac_sim.recording.layout import recording_csv
from vistac_sim.recording.session import simulate_session
from vistac_sim.render.png import encode_png
from vistac_sim.render.shot_render import render_mask, render_with_effects
from vistac_sim.render.topview import finger_boxes, px_per_m

STREAMS = ("grasp", "grasp_effects", "force_effects", "image_effects", "session",
           "sensor_effects")
FALLBACK_ROUNDS = 5  # passes over the library before a configuration gives up
GRASP_EFFECT_TRIES = 10  # draws of the grasp effects per repeat before the unperturbed grasp


@dataclass
class Configuration:
    """What one configuration adds to the dataset."""

    row: dict
    presses: list[dict]
    png: bytes
    recording: bytes | None = None  # RH8D/FTS-3 CSV of the session (only with --recordings)
    mask: bytes | None = None  # label PNG of the image (only with --masks)


class ConfigStreams:
    """Independent generators of one configuration, derived from (seed, config_id) only.

    Each stream is made on first use, so the stream of a disabled effect costs nothing.
    """

    def __init__(self, seed: int, config_id: int):
        self.key = (seed, config_id)
        self._made: dict[str, np.random.Generator] = {}

    def __getitem__(self, name: str) -> np.random.Generator:
        if name not in self._made:
            # = default_rng([...]), built directly (a quarter cheaper, the same stream)
            self._made[name] = np.random.Generator(np.random.PCG64(np.random.SeedSequence(
                [*self.key, STREAMS.index(name), 0x5EED])))
        return self._made[name]


def make_configuration(config_id: int, seed: int, scenes: RigCache, cfg: GenerateCfg,
                       pipeline: Pipeline, first: int | None = None) -> Configuration:
    """Draw, press, check, label and render configuration `config_id`.

    It uses object `first` of the library: the plan's `object_index(seed, config_id,
    len(scenes.specs))`, which a chunk knows already (computed here if None).

    An object that gives no valid grasp in `max_redraws` draws hands the configuration on to the
    next object of the library (in a fixed order, so the result stays a pure function of the
    seed; after the last object the first one again, for `FALLBACK_ROUNDS` rounds); the rejected
    draws are kept in the `failed_objects` column.

    Raises:
        RuntimeError: when no object of the library gave a valid grasp.
    """
    rng = ConfigStreams(seed, config_id)
    n_obj = len(scenes.specs)
    if first is None:
        first = object_index(seed, config_id, n_obj)
    failed: dict[str, Counter] = {}
    for j in range(n_obj * FALLBACK_ROUNDS):
        scene = scenes.get((first + j) % n_obj)
        try:
            grasp, res, normal, redraws = draw_grasp(scene, rng["grasp"], cfg)
            break
        except NoValidGrasp as exc:
            failed.setdefault(exc.object_id, Counter()).update(exc.redraws)
    else:
        raise RuntimeError(f"configuration {config_id}: no object gave a valid grasp "
                           f"({json.dumps(failed)})")
    mask = None
    if pipeline.image:  # the image, its boxes and camera columns follow the sampled view
        rgb, boxes, view_cols, mask = render_with_effects(
            scene.view, scene.press.data, pipeline, cfg.render, rng["image_effects"],
            masks=cfg.render.masks)
    else:
        boxes = finger_boxes(scene.model, scene.press.data, scene.ids, cfg.render)
        rgb, view_cols = scene.view.render(scene.press.data), {}
        if cfg.render.masks:
            mask = render_mask(scene.view, scene.press.data)
    png = encode_png(rgb, grainy=grainy_frames(cfg))
    clean = res.force_sensor
    fallbacks = 0
    if pipeline.changes_physics:
        solved = [_solve_repeat(scene, pipeline, grasp, rng["grasp_effects"])
                  for _ in range(cfg.repeats)]
        fallbacks = sum(f is None for f in solved)
        forces = np.stack([clean if f is None else f for f in solved])
    else:
        forces = np.broadcast_to(clean, (cfg.repeats, 2, 3)).copy()
    forces = pipeline.apply_force(forces, rng["force_effects"])
    recording = None
    if pipeline.needs_series or cfg.recording.write:
        session = simulate_session(forces, pipeline, cfg.recording, rng["session"],
                                   rng["sensor_effects"])
        forces = session.readings
        recording = recording_csv(session) if cfg.recording.write else None
    labels = unit_labels(forces)
    row = _config_row(config_id, scene.obj, grasp, res, clean, normal, boxes, cfg)
    row["grasp_effect_fallbacks"] = fallbacks  # repeats that kept the unperturbed force
    row["redraws"] = int(sum(redraws.values()))
    row["redraw_reasons"] = redraw_cell(redraws)
    row["failed_objects"] = failed_objects_cell(failed)
    row |= view_cols
    return Configuration(
        row=row,
        presses=press_rows(config_id, forces, labels),
        png=png,
        recording=recording,
        mask=encode_png(mask) if mask is not None else None,
    )


def grainy_frames(cfg: GenerateCfg) -> bool:
    """Whether the config's images carry sensor noise or JPEG (PNG-encoded as grainy)."""
    return cfg.effects.sensor_noise is not None or cfg.effects.jpeg is not None


def _solve_repeat(scene: ObjectRig, pipeline: Pipeline, grasp: Grasp,
                  rng: np.random.Generator) -> np.ndarray | None:
    """(2, 3) sensor-frame force of one repeat under the grasp effects.

    Every repeat's solve passes the checks of the first one (`solve`: the press, the collision
    shape, the friction cone around the mesh normal). A perturbed grasp that is rejected is drawn
    again, up to `GRASP_EFFECT_TRIES` times;
    None if every try was rejected (the caller keeps the unperturbed force and counts it in the
    `grasp_effect_fallbacks` column).
    """
    for _ in range(GRASP_EFFECT_TRIES):
        try:
            return solve(scene, pipeline.apply_grasp(grasp, rng), scene.cfg)[0].force_sensor
        except RejectedSample:
            continue
    return None


_FINGER_COLUMNS = {f: [f"target_{f}_x", f"target_{f}_y", f"approach_{f}_x", f"approach_{f}_y",
                       f"push_{f}_x", f"push_{f}_y", f"tip_{f}_x", f"tip_{f}_y",
                       f"penetration_{f}", *box_columns(f), *clean_force_columns(f),
                       *normal_columns(f)] for f in FINGERS}
"""A configuration's per-finger columns, in order (made once: a row is built per configuration)."""


def _config_row(config_id, obj: BuiltObject, grasp: Grasp, res: PressResult, clean, normal,
                boxes, cfg: GenerateCfg) -> dict:
    row = {
        "config_id": config_id,
        "object_id": obj.object_id,
        "object_family": obj.spec.family,
        "image": f"{config_id:06d}.png",
        "object_x": float(grasp.object_xy[0]),
        "object_y": float(grasp.object_xy[1]),
        "object_yaw": float(grasp.object_yaw),
        "camera_x": 0.0,
        "camera_y": 0.0,
        "px_per_m": px_per_m(cfg.render),
    }
    values = zip(grasp.target.tolist(), grasp.approach.tolist(), grasp.push_dirs.tolist(),
                 res.tip.tolist(), res.penetration.tolist(), np.asarray(boxes).tolist(),
                 np.asarray(clean).tolist(), np.asarray(normal).tolist(), strict=True)
    for f, (target, approach, push, tip, pen, box, force, n) in zip(FINGERS, values, strict=True):
        row.update(zip(_FINGER_COLUMNS[f], [*target, *approach, *push, *tip[:2], pen, *box,
                                            *force, *n], strict=True))
    return row
