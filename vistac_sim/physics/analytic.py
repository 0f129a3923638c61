"""Analytic friction check: a flat face pressed at a known push-to-normal angle.

Coulomb friction predicts the settled force: under stick it follows the push, under slip it lies
on the friction cone's edge, so ``angle(force, normal) = min(angle(push, normal), atan(mu))``.
Two faces test the two lateral springs of a fingertip: a vertical wall pushed at a yaw angle
(the sideways spring) and a face tilted about a horizontal axis, pushed horizontally (the up/down
spring). The thumb presses the opposite, vertical face along its normal. Used by
`tests/sim/test_friction.py` and `benchmarks/friction_stats.py`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh
from shapely.geometry import box

from vistac.config import apply
from vistac_sim.generate.config import GenerateCfg
from vistac_sim.generate.rigs import ObjectRig
from vistac_sim.geometry import angle_deg
from vistac_sim.hand.grasp import Grasp
from vistac_sim.objects.library import BuiltObject, ObjectSpec
from vistac_sim.physics.normals import surface_normals

HALF = 0.025  # m, half side of the pressed block
HEIGHT = 0.04  # m, its height
FACES = ("wall", "slope_up", "slope_down")


@dataclass
class AnalyticPress:
    """One press of the analytic check (index finger)."""

    face: str
    friction: float
    push_deg: float
    expected_deg: float  # min(push, atan mu)
    measured_deg: float  # angle between the settled force and the face normal

    @property
    def error_deg(self) -> float:
        return self.measured_deg - self.expected_deg


def expected_angle_deg(push_deg: float, friction: float) -> float:
    """Coulomb's prediction of the force-to-normal angle of a settled press."""
    return float(min(push_deg, np.degrees(np.arctan(friction))))


def face_object(face: str, push_deg: float, finger_height: float) -> BuiltObject:
    """The block whose +x face is pressed: vertical ("wall") or tilted by `push_deg` about y so
    that its normal points up ("slope_up") or down ("slope_down")."""
    tilt = 0.0 if face == "wall" else np.radians(push_deg) * (1 if face == "slope_up" else -1)
    front = [HALF - (z - finger_height) * np.tan(tilt) for z in (0.0, HEIGHT)]
    verts = [(x, y, z) for (x, z) in ((-HALF, 0.0), (-HALF, HEIGHT), (front[0], 0.0),
                                      (front[1], HEIGHT)) for y in (-HALF, HALF)]
    mesh = trimesh.convex.convex_hull(np.array(verts))
    spec = ObjectSpec(f"{face}_{push_deg:g}", "analytic", 0, 2 * HALF, HEIGHT)
    return BuiltObject(spec, mesh, [mesh], box(-HALF, -HALF, HALF, HALF), (0.25, 0.3, 0.7))


def face_grasp(face: str, push_deg: float, tip_radius: float) -> Grasp:
    """Index on the +x face, pushed `push_deg` off its normal (yaw for the wall, horizontal for
    the slopes); thumb on the -x face along its normal. The index starts clear of a tilted face
    (its target moves out by the extra reach of the tilt at the pad's height)."""
    a = np.radians(push_deg)
    if face == "wall":
        index_push, x = [-np.cos(a), np.sin(a)], HALF
    else:
        index_push, x = [-1.0, 0.0], HALF + tip_radius * (1 / np.cos(a) - 1)
    return Grasp(np.zeros(2), 0.0, np.array([[x, 0.0], [-HALF, 0.0]]),
                 np.array([[1.0, 0.0], [-1.0, 0.0]]), np.array([index_push, [1.0, 0.0]]))


def analytic_press(face: str, push_deg: float, friction: float,
                   cfg: GenerateCfg | None = None) -> AnalyticPress:
    """Press the index finger on `face` at `push_deg` off its normal and measure the angle.

    Raises:
        RejectedSample: when the press fails a check (it should not, for pushes up to 60 deg).
    """
    cfg = apply(cfg or GenerateCfg(), {"physics": {"friction": friction}})
    obj = face_object(face, push_deg, cfg.hand.height)
    scene = ObjectRig(obj, cfg, render=False)
    grasp = face_grasp(face, push_deg, cfg.hand.tip_radius)
    res = scene.press.run(grasp)
    normal = surface_normals(scene.triangles, grasp, res, 2 * cfg.hand.tip_half_length)
    measured = float(angle_deg(res.force_sensor[0], res.rotation[0].T @ normal[0]))
    return AnalyticPress(face, friction, push_deg, expected_angle_deg(push_deg, friction),
                         measured)
