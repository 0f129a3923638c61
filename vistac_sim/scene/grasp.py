"""A grasp configuration: object pose, contact targets and approach directions (world frame).

Grasps are drawn by `vistac_sim.generate.grasps`, posed in the scene by the press, and moved by
scene-stage effects (`Grasp.moved`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from vistac_sim.geometry import rot2, unit


@dataclass(frozen=True)
class Grasp:
    """One grasp configuration in world coordinates (metres, radians), fingers (index, thumb)."""

    object_xy: np.ndarray  # (2,) object origin on the table
    object_yaw: float
    target: np.ndarray  # (2, 2) contact targets, world xy
    normal: np.ndarray  # (2, 2) outward outline normals at the targets, world xy
    approach: np.ndarray  # (2, 2) unit approach directions, world xy

    def start(self, tip_radius: float, standoff: float) -> np.ndarray:
        """(2, 2) world xy of each tip's front-cap centre before the press.

        The cap would touch the target after moving `standoff` along the approach.
        """
        return self.target + self.normal * tip_radius - self.approach * standoff

    def moved(self, **changes) -> Grasp:
        return replace(self, **changes)


def to_world(g: Grasp) -> Grasp:
    """Turn a grasp drawn in the object frame into world coordinates (rotate by yaw, shift)."""
    r = rot2(g.object_yaw)
    return g.moved(target=g.target @ r.T + g.object_xy, normal=unit(g.normal @ r.T),
                   approach=unit(g.approach @ r.T))
