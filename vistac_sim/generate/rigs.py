"""What a worker builds once per object, and pressing a grasp on it.

`ObjectRig` bundles the compiled model, the press, the renderer, the outline sampler and the
normal look-up of one object; `RigCache` keeps a few of them. `solve` presses one grasp and
checks its labels; `draw_grasp` draws grasps until one passes.
"""

from __future__ import annotations

from collections import Counter, OrderedDict
from dataclasses import replace

import numpy as np

from vistac.dataset import FINGERS
from vistac_sim.effects.shadows import shadow_map_size
from vistac_sim.generate.config import GenerateCfg
from vistac_sim.generate.grasps import OutlineSampler
from vistac_sim.hand.grasp import Grasp
from vistac_sim.hand.model import compile_model
from vistac_sim.objects.library import BuiltObject, ObjectSpec, build_object
from vistac_sim.physics.checks import RejectedSample, check_collision_shape, check_physics
from vistac_sim.physics.normals import TriangleIndex, surface_normals
from vistac_sim.physics.press import Press, PressResult
from vistac_sim.render.topview import TopView, finger_capsules


class NoValidGrasp(RuntimeError):
    """`max_redraws` draws in a row on one object were rejected; `redraws` counts the reasons,
    `details` names what each reason last said (e.g. which MuJoCo warning)."""

    def __init__(self, object_id: str, redraws: Counter, details: dict[str, str] | None = None):
        self.object_id = object_id
        self.redraws = redraws
        self.details = details or {}
        super().__init__(f"object {object_id} gave {self.summary()}")

    def summary(self) -> str:
        """"no valid grasp in 60 draws: 60 x mujoco_warning (mjWARN_BADQACC)", reasons by count."""
        return no_valid_grasp_text(self.redraws, self.details)


def no_valid_grasp_text(redraws: Counter | dict[str, int],
                        details: dict[str, str] | None = None) -> str:
    """The failed draws of an object in words, the commonest reason first."""
    details = details or {}
    parts = [f"{n} x {r}" + (f" ({details[r]})" if r in DETAILED and r in details else "")
             for r, n in sorted(redraws.items(), key=lambda kv: (-kv[1], kv[0]))]
    return f"no valid grasp in {sum(redraws.values())} draws: " + ", ".join(parts)


DETAILED = {"mujoco_warning", "non_finite"}
"""Reasons whose detail (which warning) is worth naming in the final error."""


class ObjectRig:
    """Everything a worker builds once per object.

    `cfg` is the run's config with the hand at the object's press height (`BuiltObject`).
    """

    def __init__(self, obj: BuiltObject, cfg: GenerateCfg, render: bool = True):
        if obj.press_height is not None and obj.press_height != cfg.hand.height:
            cfg = replace(cfg, hand=replace(cfg.hand, height=obj.press_height))
        self.obj, self.cfg = obj, cfg
        self.model, self.ids = compile_model(obj, cfg)
        self.press = Press(self.model, self.ids, cfg)
        self.sampler = OutlineSampler.of(obj, cfg)
        self.triangles = TriangleIndex(obj.mesh.vertices, obj.mesh.faces)
        self.view = TopView(self.model, self.ids, cfg.render,
                            shadow_size=shadow_map_size(cfg.effects)) if render else None

    def close(self) -> None:
        if self.view is not None:
            self.view.close()


class RigCache:
    """A small LRU of `ObjectRig`s keyed by object index (renderers are costly to keep)."""

    def __init__(self, specs: list[ObjectSpec], cfg: GenerateCfg, size: int = 6, cache_dir=None):
        self.specs, self.cfg, self.size, self.cache_dir = specs, cfg, size, cache_dir
        self._rigs: OrderedDict[int, ObjectRig] = OrderedDict()

    def get(self, index: int) -> ObjectRig:
        if index in self._rigs:
            self._rigs.move_to_end(index)
            return self._rigs[index]
        obj = build_object(self.specs[index], self.cfg.hand.height, self.cfg.objects.min_wall,
                           self.cache_dir, self.cfg.objects.min_height,
                           self.cfg.objects.shape_tolerance)
        rig = ObjectRig(obj, self.cfg)
        self._rigs[index] = rig
        if len(self._rigs) > self.size:
            self._rigs.popitem(last=False)[1].close()
        return rig

    def close(self) -> None:
        for rig in self._rigs.values():
            rig.close()
        self._rigs.clear()


def solve(rig: ObjectRig, grasp: Grasp, cfg: GenerateCfg) -> tuple[PressResult, np.ndarray]:
    """Press, then check the noise-free forces against the mesh normals (sensor frame).

    Returns:
        The press result and the (2, 3) outward surface normals in each sensor frame.

    Raises:
        RejectedSample: from the press or the physical checks.
    """
    res = rig.press.run(grasp)
    world = surface_normals(rig.triangles, grasp, res, 2 * cfg.hand.tip_half_length)
    check_collision_shape(res.contact_normals, [c[:, 3] for c in res.pad_contacts], world,
                          cfg.physics.shape_tolerance_deg)
    normal = np.einsum("kji,kj->ki", res.rotation, world)
    check_physics(res.force_sensor, normal, cfg.physics.friction, cfg.physics.cone_tolerance_deg)
    return res, normal


def check_in_view(rig: ObjectRig, cfg: GenerateCfg) -> None:
    """Both fingertips (each pad capsule, widened by its radius) must lie inside the clean top
    view, so that every kept image shows both fingers.

    Raises:
        RejectedSample: "finger_outside_view", naming the finger.
    """
    half = cfg.render.view_extent / 2
    for name, finger in zip(FINGERS, finger_capsules(rig.model, rig.press.data, rig.ids),
                            strict=True):
        a, b, r = finger[0]  # the pad
        if max(abs(a[0]), abs(a[1]), abs(b[0]), abs(b[1])) + r > half:
            raise RejectedSample("finger_outside_view", f"{name} fingertip leaves the "
                                 f"{cfg.render.view_extent * 1000:g} mm view")


def draw_grasp(rig: ObjectRig, rng: np.random.Generator,
               cfg: GenerateCfg) -> tuple[Grasp, PressResult, np.ndarray, Counter]:
    """Draw grasps until one passes every check.

    Returns:
        The grasp, its press, the sensor-frame surface normals and the rejected draws by reason.

    Raises:
        NoValidGrasp: when `max_redraws` draws in a row were rejected (names the object).
    """
    redraws: Counter = Counter()
    details: dict[str, str] = {}
    for _ in range(cfg.grasp.max_redraws):
        try:
            grasp = rig.sampler.sample(rng)
            res, normal = solve(rig, grasp, cfg)
            check_in_view(rig, cfg)
            return grasp, res, normal, redraws
        except RejectedSample as exc:
            redraws[exc.reason] += 1
            details[exc.reason] = exc.detail
    raise NoValidGrasp(rig.obj.object_id, redraws, details)
