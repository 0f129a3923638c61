"""Named hard scenes (a test helper): each yields finite labels that pass the physical checks or
a named rejection.

Every case builds one object and one grasp in the object frame (object at the origin, yaw 0), runs
the same checks as `vistac generate` (grasp reachability, press checks, friction cone around the
full-resolution mesh normal) and reports the outcome. `test_hard_cases.py` runs the suite.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import trimesh
from shapely import affinity
from shapely.geometry import Point, Polygon, box
from shapely.ops import unary_union

from vistac.config import apply
from vistac.dataset import unit_labels
from vistac_sim.generate.config import GenerateCfg
from vistac_sim.generate.rigs import ObjectRig, solve
from vistac_sim.geometry import angle_deg, unit
from vistac_sim.hand.grasp import Grasp
from vistac_sim.objects.library import BuiltObject, ObjectSpec, extruded_object
from vistac_sim.objects.meshes import mesh_section, scale_to_footprint
from vistac_sim.physics.checks import RejectedSample

# Every rejection reason of grasp sampling, the press and the physical checks.
KNOWN_REASONS = {"unreachable", "no_opposing_thumb", "fingers_overlap", "start_penetrates",
                 "mujoco_warning", "non_finite", "no_contact", "shaft_contact", "not_settled",
                 "penetration", "pulling_force", "outside_friction_cone", "collision_shape_off",
                 "finger_outside_view"}


def thin_wall_u(L: float, wall: float) -> Polygon:
    """A U outline with walls of exactly `wall` metres (the thin-wall hard case)."""
    h = 0.8 * L
    poly = unary_union([box(0, 0, L, wall), box(0, 0, wall, h), box(L - wall, 0, L, h)])
    return affinity.translate(poly, -poly.centroid.x, -poly.centroid.y)


@dataclass
class Outcome:
    """What a hard case gave: labels and checks, or the rejection reason."""

    name: str
    accepted: bool
    reason: str = ""
    labels: np.ndarray | None = None  # (2, 2) unit (r_y, r_z) of index and thumb
    force: np.ndarray | None = None  # (2, 3) sensor frame, N
    normal: np.ndarray | None = None  # (2, 3) sensor frame
    angle_to_normal_deg: np.ndarray | None = None
    penetration: np.ndarray | None = None


CASES: dict[str, Callable[[GenerateCfg], tuple[BuiltObject, Grasp]]] = {}
CHANGES: dict[str, dict] = {}
"""Config changes a case presses under (`vistac.config.apply` form), by case name."""


def case(name: str, **changes):
    def deco(fn):
        CASES[name] = fn
        CHANGES[name] = changes
        return fn

    return deco


def _grasp(targets, normals, approaches) -> Grasp:
    return Grasp(np.zeros(2), 0.0, np.asarray(targets, float), unit(np.asarray(normals, float)),
                 unit(np.asarray(approaches, float)))


def _extrusion(name: str, poly, height: float = 0.04) -> BuiltObject:
    return extruded_object(ObjectSpec(name, "hard_case", 0, 0.0, height), poly)


def _pinch_x(half_width: float) -> Grasp:
    """Index from +x, thumb from -x, both along the normal."""
    return _grasp([[half_width, 0], [-half_width, 0]], [[1, 0], [-1, 0]], [[-1, 0], [1, 0]])


@case("grazing_85deg")
def _grazing(cfg):
    ang = np.radians(85)
    g = _pinch_x(0.025)
    return _extrusion("box50", box(-0.025, -0.025, 0.025, 0.025)), g.moved(
        approach=unit(np.array([[-np.cos(ang), np.sin(ang)], [1.0, 0.0]])))


def _wall_push(push_deg: float) -> tuple[BuiltObject, Grasp]:
    """The 50 mm box; the index pushes its +x face `push_deg` off the normal (yaw), the thumb
    pushes the -x face along its normal."""
    a = np.radians(push_deg)
    return _extrusion("box50", box(-0.025, -0.025, 0.025, 0.025)), _pinch_x(0.025).moved(
        approach=unit(np.array([[-np.cos(a), np.sin(a)], [1.0, 0.0]])))


def _cone_deg(cfg: GenerateCfg) -> float:
    return float(np.degrees(np.arctan(cfg.physics.friction)))


@case("stick_inside_cone_edge")
def _stick(cfg):
    """Pushed 2 deg inside the friction cone: the pad sticks, the force follows the push."""
    return _wall_push(max(_cone_deg(cfg) - 2.0, 0.0))


@case("slip_past_cone_edge")
def _slip(cfg):
    """Pushed 2 deg outside the friction cone: the pad slips until the force lies on its edge."""
    return _wall_push(_cone_deg(cfg) + 2.0)


@case("near_zero_normal_force", hand={"press_force": 0.01, "standoff": 2e-5})
def _faint(cfg):
    """A 10 mN push (ten FTS-3 resolution steps) 20 deg off the normal, from 20 um away."""
    return _wall_push(20.0)


@case("grazing_70deg_friction")
def _grazing_friction(cfg):
    """70 deg off the normal: with friction the pad slips to the cone's edge and holds there
    (its springs take the rest); frictionless it slides along the face out of travel."""
    return _wall_push(70.0)


@case("sharp_convex_corner")
def _corner(cfg):
    d = unit(np.array([[1.0, 1.0], [-1.0, -1.0]]))
    return _extrusion("box50", box(-0.025, -0.025, 0.025, 0.025)), _grasp(
        [[0.025, 0.025], [-0.025, -0.025]], d, -d)


@case("thin_wall_1mm")
def _thin_wall(cfg):
    poly = thin_wall_u(0.06, 0.001)
    x0, _, x1, _ = poly.bounds
    y = poly.centroid.y + 0.01
    return _extrusion("u_wall1mm", poly), _grasp([[x1, y], [x0, y]], [[1, 0], [-1, 0]],
                                                 [[-1, 0], [1, 0]])


@case("deep_concave_pocket")
def _pocket(cfg):
    wall = 0.012
    poly = thin_wall_u(0.08, wall)
    _, y0, _, _ = poly.bounds
    inner = y0 + wall  # the pocket's floor; the finger enters from the open side (+y)
    return _extrusion("u_pocket", poly), _grasp([[0.0, inner], [0.0, y0]], [[0, 1], [0, -1]],
                                                [[0, -1], [0, 1]])


@case("very_small_object")
def _small(cfg):
    return _extrusion("pin6mm", Point(0, 0).buffer(0.003, quad_segs=16)), _pinch_x(0.003)


@case("very_large_object")
def _large(cfg):
    return _extrusion("box200", box(-0.1, -0.05, 0.1, 0.05)), _pinch_x(0.1)


@case("mesh_100k_faces")
def _dense_mesh(cfg):
    obj = _icosphere_327k(cfg.hand.height)
    return obj, _pinch_x((obj.section.bounds[2] - obj.section.bounds[0]) / 2)


@functools.lru_cache(maxsize=2)
def _icosphere_327k(finger_height: float) -> BuiltObject:
    mesh = scale_to_footprint(trimesh.creation.icosphere(subdivisions=7), 0.05)  # 327,680 faces
    section = mesh_section(mesh, finger_height, "icosphere")
    return BuiltObject(ObjectSpec("icosphere_327k", "hard_case", 0, 0.05, 0.05), mesh,
                       [mesh.convex_hull], section, (0.25, 0.3, 0.7))


@case("fingers_same_point")
def _same_point(cfg):
    return _extrusion("box50", box(-0.025, -0.025, 0.025, 0.025)), _grasp(
        [[0.025, 0.0], [0.025, 0.001]], [[1, 0], [1, 0]], [[-1, 0], [-1, 0]])


def run_case(name: str, cfg: GenerateCfg | None = None) -> Outcome:
    """Build and press one named hard case; never raises for a rejected grasp."""
    cfg = apply(cfg or GenerateCfg(), CHANGES[name])
    obj, grasp = CASES[name](cfg)
    scene = ObjectRig(obj, cfg, render=False)
    try:
        scene.sampler.check(grasp)
        res, normal = solve(scene, grasp, cfg)
    except RejectedSample as exc:
        return Outcome(name, False, reason=exc.reason)
    return Outcome(name, True, labels=unit_labels(res.force_sensor), force=res.force_sensor,
                   normal=normal, angle_to_normal_deg=angle_deg(res.force_sensor, normal),
                   penetration=res.penetration)
