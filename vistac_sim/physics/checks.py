"""Rejections: what makes a grasp configuration unusable, and the physical check of a press."""

from __future__ import annotations

import numpy as np

from vistac_sim.geometry import angle_deg


class RejectedSample(Exception):
    """A grasp configuration that cannot yield trustworthy labels; `reason` is a short name.

    Raised by grasp sampling (the fingers do not fit), by the press (a failed solve check) and
    by `check_physics`; `vistac generate` redraws the grasp and counts the reason.
    """

    def __init__(self, reason: str, detail: str = ""):
        super().__init__(f"{reason}: {detail}" if detail else reason)
        self.reason = reason
        self.detail = detail


def check_physics(force: np.ndarray, normal: np.ndarray, friction: float, tol_deg: float) -> None:
    """Physical checks of a noise-free press (sensor frame): pushing force inside the cone.

    Raises:
        RejectedSample: "pulling_force" (F_z >= 0) or "outside_friction_cone".
    """
    if not np.all(force[:, 2] < 0):
        raise RejectedSample("pulling_force", "a pad is not pushed (F_z >= 0)")
    limit = np.degrees(np.arctan(friction)) + tol_deg
    # angle <= limit  <=>  cos(angle) >= cos(limit): no angle is computed for a press that
    # passes (most of them)
    along = (force * normal).sum(1)
    lengths = np.sqrt((force * force).sum(1) * (normal * normal).sum(1))
    if np.any(along < np.cos(np.radians(limit)) * lengths):
        ang = angle_deg(force, normal)
        raise RejectedSample("outside_friction_cone",
                             f"force {ang.max():.1f} deg off the normal (limit {limit:.1f})")


def check_collision_shape(contact_normals, weights, mesh_normals: np.ndarray,
                          tol_deg: float) -> None:
    """The collision geometry MuJoCo pressed must face where the labelled mesh faces: per pad,
    the normal-force-weighted mean of its contact normals (world, out of the object) within
    `tol_deg` of the full-resolution mesh normal there (`mesh_normals`, (2, 3) world). Without
    friction the label follows the collision normal, so this bounds a frictionless label's
    error against the true surface normal; with friction it bounds the cone's axis.

    Raises:
        RejectedSample: "collision_shape_off", naming the angle.
    """
    for normals, w, mesh_n in zip(contact_normals, weights, mesh_normals, strict=True):
        mean = (normals * np.maximum(w, 1e-12)[:, None]).sum(0)
        length = float(np.sqrt(mean @ mean) * np.sqrt(mesh_n @ mesh_n))
        if length == 0 or float(mean @ mesh_n) < np.cos(np.radians(tol_deg)) * length:
            ang = float(angle_deg(mean[None], mesh_n[None])[0]) if length else 180.0
            raise RejectedSample("collision_shape_off", f"the collision normal is {ang:.2f} deg "
                                 f"off the mesh normal (limit {tol_deg:g})")
