"""A grasp configuration: object pose, contact targets, finger axes and push directions (world).

A finger's approach direction is its axis (its sensor's z, as drawn in the image); the push is
the direction the hand drives it in, the hand's closing axis, which may differ.

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
    approach: np.ndarray  # (2, 2) unit approach directions = finger axes (sensor z), world xy
    push: np.ndarray | None = None  # (2, 2) unit push directions (the hand's closing axis);
    # None: each finger pushes along its own axis

    @property
    def push_dirs(self) -> np.ndarray:
        """(2, 2) unit directions along which the fingertips are pushed, world xy."""
        return self.approach if self.push is None else self.push

    def start(self, tip_radius: float, standoff: float) -> np.ndarray:
        """(2, 2) world xy of each tip's front-cap centre before the press.

        The cap would touch the target after moving `standoff` along its push direction.
        """
        return self.target + self.normal * tip_radius - self.push_dirs * standoff

    def moved(self, **changes) -> Grasp:
        return replace(self, **changes)


def to_world(g: Grasp) -> Grasp:
    """Turn a grasp drawn in the object frame into world coordinates (rotate by yaw, shift)."""
    r = rot2(g.object_yaw)
    return g.moved(target=g.target @ r.T + g.object_xy, normal=unit(g.normal @ r.T),
                   approach=unit(g.approach @ r.T),
                   push=None if g.push is None else unit(g.push @ r.T))
