"""One grasp configuration end to end: grasp, press(es), checks, labels, render.

`ObjectScene` bundles everything built once per object inside a worker (compiled model, press,
renderer, outline sampler, normal look-up). `make_configuration` turns a configuration id into
its table rows and PNG, drawing all randomness from generators derived from (seed, config_id),
so the result does not depend on which worker runs it or in which order.
"""

from __future__ import annotations

from collections import Counter, OrderedDict
from dataclasses import dataclass

import numpy as np

from vistac_sim.config import GenerateCfg
from vistac_sim.effects import Pipeline
from vistac_sim.errors import RejectedSample
from vistac_sim.geometry import TriangleIndex, angle_deg, closest_on_segment, rot2, unit
from vistac_sim.grasp import Grasp, OutlineSampler
from vistac_sim.image_effects import render_with_effects, shadow_map_size
from vistac_sim.objects import ObjectSpec, SceneObject, build_object
from vistac_sim.press import Press, PressResult
from vistac_sim.recordings import recording_csv
from vistac_sim.render import TopView, encode_png, finger_boxes, px_per_m
from vistac_sim.scene import FINGERS, compile_scene
from vistac_sim.session import simulate_session

_FLAT_COS = np.cos(np.radians(0.5))  # faces this close in direction count as one flat surface
STREAMS = ("grasp", "scene_effects", "force_effects", "image_effects", "session",
           "sensor_effects")
SCENE_EFFECT_TRIES = 10  # draws of the scene effects per repeat before the unperturbed grasp


class ObjectScene:
    """Everything a worker builds once per object."""

    def __init__(self, obj: SceneObject, cfg: GenerateCfg, render: bool = True):
        self.obj, self.cfg = obj, cfg
        self.model, self.ids = compile_scene(obj, cfg)
        self.press = Press(self.model, self.ids, cfg)
        self.sampler = OutlineSampler(obj.section, cfg)
        self.triangles = TriangleIndex(obj.mesh.vertices, obj.mesh.faces)
        self.view = TopView(self.model, self.ids, cfg.render,
                            shadow_size=shadow_map_size(cfg.effects)) if render else None

    def close(self) -> None:
        if self.view is not None:
            self.view.close()

    def surface_normals(self, grasp: Grasp, res: PressResult) -> np.ndarray:
        """(2, 3) outward normal of the full-resolution mesh at each pad's contact, world frame.

        Per contact, s is the point of the pad capsule's axis nearest MuJoCo's contact point (the
        centre of the pad sphere that touches there; it lies outside the object) and q the mesh
        point nearest s, searched among the faces near the contact point (a face the pad does not
        touch is farther from s than the touched ones, and a second touched face makes its own
        contact). Inside a face (or on an edge between coplanar faces) the normal is the
        face normal. On a sharp edge or corner it is (s - q)/|s - q|, the member of the normal
        cone that points at the pad, which is the direction a frictionless contact pushes along
        there. Several contacts of one pad are averaged with their normal-force weights.
        """
        # World <-> object frame: rotation about z by the object's yaw, then its offset.
        rot = np.eye(3)
        rot[:2, :2] = rot2(grasp.object_yaw)
        origin = np.array([grasp.object_xy[0], grasp.object_xy[1], 0.0])
        reach = 2 * self.cfg.hand.tip_half_length
        out = np.zeros((2, 3))
        for k in range(2):
            axis = np.array([grasp.approach[k, 0], grasp.approach[k, 1], 0.0])
            tip = res.tip[k]
            for *pos, weight in res.pad_contacts[k]:
                centre = closest_on_segment(np.asarray(pos), tip - axis * reach, tip)
                q_obj, face_n = self.triangles.closest(rot.T @ (centre - origin),
                                                       around=rot.T @ (np.asarray(pos) - origin))
                if np.all(face_n @ face_n[0] > _FLAT_COS):
                    n = rot @ face_n[0]
                else:
                    n = unit(centre - (rot @ q_obj + origin))
                out[k] += max(weight, 1e-12) * n
        return unit(out)


class SceneCache:
    """A small LRU of `ObjectScene`s keyed by object index (renderers are costly to keep)."""

    def __init__(self, specs: list[ObjectSpec], cfg: GenerateCfg, size: int = 6, cache_dir=None):
        self.specs, self.cfg, self.size, self.cache_dir = specs, cfg, size, cache_dir
        self._scenes: OrderedDict[int, ObjectScene] = OrderedDict()

    def get(self, index: int) -> ObjectScene:
        if index in self._scenes:
            self._scenes.move_to_end(index)
            return self._scenes[index]
        obj = build_object(self.specs[index], self.cfg.hand.height, self.cfg.objects.min_wall,
                           self.cache_dir)
        scene = ObjectScene(obj, self.cfg)
        self._scenes[index] = scene
        if len(self._scenes) > self.size:
            self._scenes.popitem(last=False)[1].close()
        return scene

    def close(self) -> None:
        for scene in self._scenes.values():
            scene.close()
        self._scenes.clear()


@dataclass
class Configuration:
    """What one configuration adds to the dataset."""

    row: dict
    presses: list[dict]
    png: bytes
    recording: bytes | None = None  # RH8D/FTS-3 CSV of the session (only with --recordings)


class ConfigStreams:
    """Independent generators of one configuration, derived from (seed, config_id) only.

    Each stream is made on first use, so the stream of a disabled effect costs nothing.
    """

    def __init__(self, seed: int, config_id: int):
        self.key = (seed, config_id)
        self._made: dict[str, np.random.Generator] = {}

    def __getitem__(self, name: str) -> np.random.Generator:
        if name not in self._made:
            self._made[name] = np.random.default_rng([*self.key, STREAMS.index(name), 0x5EED])
        return self._made[name]


def object_index(seed: int, config_id: int, n_objects: int) -> int:
    """Which object of the library configuration `config_id` uses."""
    return int(np.random.SeedSequence([seed, config_id, 7]).generate_state(1, np.uint64)[0]
               % n_objects)


def check_physics(force: np.ndarray, normal: np.ndarray, friction: float, tol_deg: float) -> None:
    """Physical checks of a noise-free press (sensor frame): pushing force inside the cone.

    Raises:
        RejectedSample: "pulling_force" (F_z >= 0) or "outside_friction_cone".
    """
    if not np.all(force[:, 2] < 0):
        raise RejectedSample("pulling_force", "a pad is not pushed (F_z >= 0)")
    limit = np.degrees(np.arctan(friction)) + tol_deg
    ang = angle_deg(force, normal)
    if np.any(ang > limit):
        raise RejectedSample("outside_friction_cone",
                             f"force {ang.max():.1f} deg off the normal (limit {limit:.1f})")


def unit_labels(forces: np.ndarray) -> np.ndarray:
    """(..., 2) unit (r_y, r_z) of forces (..., 3); a zero (y, z) force gives (0, -1)."""
    yz = forces[..., 1:]
    n = np.linalg.norm(yz, axis=-1, keepdims=True)
    safe = np.where(n > 0, n, 1.0)
    return np.where(n > 0, yz / safe, np.array([0.0, -1.0]))


def solve(scene: ObjectScene, grasp: Grasp, cfg: GenerateCfg) -> tuple[PressResult, np.ndarray]:
    """Press, then check the noise-free forces against the mesh normals (sensor frame).

    Returns:
        The press result and the (2, 3) outward surface normals in each sensor frame.

    Raises:
        RejectedSample: from the press or the physical checks.
    """
    res = scene.press.run(grasp)
    normal = np.einsum("kji,kj->ki", res.rotation, scene.surface_normals(grasp, res))
    check_physics(res.force_sensor, normal, cfg.physics.friction, cfg.physics.cone_tolerance_deg)
    return res, normal


def draw_grasp(scene: ObjectScene, rng: np.random.Generator,
               cfg: GenerateCfg) -> tuple[Grasp, PressResult, np.ndarray, Counter]:
    """Draw grasps until one passes every check.

    Returns:
        The grasp, its press, the sensor-frame surface normals and the rejected draws by reason.

    Raises:
        RuntimeError: when `max_redraws` draws in a row were rejected (names the object).
    """
    redraws: Counter = Counter()
    for _ in range(cfg.grasp.max_redraws):
        try:
            grasp = scene.sampler.sample(rng)
            return (grasp, *solve(scene, grasp, cfg), redraws)
        except RejectedSample as exc:
            redraws[exc.reason] += 1
    raise RuntimeError(f"object {scene.obj.object_id} gave no valid grasp in "
                       f"{cfg.grasp.max_redraws} draws ({dict(redraws)})")


def make_configuration(config_id: int, seed: int, scenes: SceneCache, cfg: GenerateCfg,
                       pipeline: Pipeline) -> Configuration:
    """Draw, press, check, label and render configuration `config_id`.

    Raises:
        RuntimeError: when `max_redraws` draws in a row were rejected (names the object).
    """
    rng = ConfigStreams(seed, config_id)
    idx = object_index(seed, config_id, len(scenes.specs))
    scene = scenes.get(idx)
    try:
        grasp, res, normal, redraws = draw_grasp(scene, rng["grasp"], cfg)
    except RuntimeError as exc:
        raise RuntimeError(f"configuration {config_id}: {exc}") from None
    if pipeline.image:  # the image, its boxes and camera columns follow the sampled view
        rgb, boxes, view_cols = render_with_effects(scene.view, scene.press.data, pipeline,
                                                    cfg.render, rng["image_effects"])
    else:
        boxes = finger_boxes(scene.model, scene.press.data, scene.ids, cfg.render)
        rgb, view_cols = scene.view.render(scene.press.data), {}
    png = encode_png(rgb)
    clean = res.force_sensor
    fallbacks = 0
    if pipeline.changes_physics:
        solved = [_solve_repeat(scene, pipeline, grasp, rng["scene_effects"])
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
    row["scene_effect_fallbacks"] = fallbacks  # repeats that kept the unperturbed force
    row["redraws"] = int(sum(redraws.values()))
    row["redraw_reasons"] = ",".join(f"{k}:{v}" for k, v in sorted(redraws.items()))
    row |= view_cols
    return Configuration(
        row=row,
        presses=[_press_row(config_id, k, forces[k], labels[k]) for k in range(cfg.repeats)],
        png=png,
        recording=recording,
    )


def _solve_repeat(scene: ObjectScene, pipeline: Pipeline, grasp: Grasp,
                  rng: np.random.Generator) -> np.ndarray | None:
    """(2, 3) sensor-frame force of one repeat under the scene effects.

    A perturbed grasp that the press rejects is drawn again, up to `SCENE_EFFECT_TRIES` times;
    None if every try was rejected (the caller keeps the unperturbed force and counts it in the
    `scene_effect_fallbacks` column).
    """
    for _ in range(SCENE_EFFECT_TRIES):
        try:
            return scene.press.run(pipeline.apply_scene(grasp, rng)).force_sensor
        except RejectedSample:
            continue
    return None


def _config_row(config_id, obj: SceneObject, grasp: Grasp, res: PressResult, clean, normal,
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
    for k, f in enumerate(FINGERS):
        row |= {
            f"target_{f}_x": grasp.target[k, 0], f"target_{f}_y": grasp.target[k, 1],
            f"approach_{f}_x": grasp.approach[k, 0], f"approach_{f}_y": grasp.approach[k, 1],
            f"tip_{f}_x": res.tip[k, 0], f"tip_{f}_y": res.tip[k, 1],
            f"penetration_{f}": res.penetration[k],
        }
        row |= {f"bbox_{f}_{c}": boxes[k, j] for j, c in enumerate("xywh")}
        row |= {f"force_clean_{f}_{c}": clean[k, j] for j, c in enumerate("xyz")}
        row |= {f"normal_{f}_{c}": normal[k, j] for j, c in enumerate("xyz")}
    return {k: (float(v) if isinstance(v, np.floating) else v) for k, v in row.items()}


def _press_row(config_id: int, repeat: int, force: np.ndarray, label: np.ndarray) -> dict:
    row = {"config_id": config_id, "repeat": repeat}
    for k, f in enumerate(FINGERS):
        row |= {f"force_{f}_{c}": float(force[k, j]) for j, c in enumerate("xyz")}
    for k, f in enumerate(FINGERS):
        row |= {f"r_y_{f}": float(label[k, 0]), f"r_z_{f}": float(label[k, 1])}
    return row
