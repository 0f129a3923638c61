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
