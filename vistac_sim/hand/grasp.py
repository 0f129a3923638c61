"""A grasp configuration: object pose, contact targets, finger axes and push directions (world).

A finger's approach direction is its axis (its sensor's z, as drawn in the image); the push is
the direction the hand drives it in, the hand's closing axis, which may differ.

Grasps are drawn by `vistac_sim.generate.grasps`, posed in the scene by the press, and moved by
grasp-stage effects (`Grasp.moved`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np


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
        return np.array(cap_starts(self.target.tolist(), self.normal.tolist(),
                                   self.push_dirs.tolist(), tip_radius, standoff))

    def moved(self, **changes) -> Grasp:
        return replace(self, **changes)


def cap_starts(target, normal, push, tip_radius: float, standoff: float) -> list[list[float]]:
    """Each tip's front-cap centre before the press (`Grasp.start`), from (2, 2) nested lists
    of targets, outward normals and push directions: the cap would touch the target after
    moving `standoff` along its push direction."""
    return [[t[i] + n[i] * tip_radius - d[i] * standoff for i in range(2)]
            for t, n, d in zip(target, normal, push, strict=True)]


def to_world(yaw: float, xy: np.ndarray, target: list, normal: list, approach: list,
             push: list) -> Grasp:
    """The grasp of an object at `xy`, turned by `yaw`, from its targets, outline normals,
    approach and push directions drawn in the object's frame ((2, 2) nested lists each): points
    are rotated and shifted, directions rotated and normalised. Python floats throughout (a grasp
    is a handful of numbers)."""
    c, s = math.cos(yaw), math.sin(yaw)
    x0, y0 = float(xy[0]), float(xy[1])

    def rotated(v: list[float]) -> tuple[float, float]:
        return v[0] * c - v[1] * s, v[0] * s + v[1] * c

    def turned(v: list[float]) -> list[float]:
        x, y = rotated(v)
        length = math.sqrt(x * x + y * y)
        return [x / length, y / length] if length > 0 else [0.0, 0.0]

    return Grasp(np.asarray(xy), yaw, np.array([[x + x0, y + y0] for x, y in map(rotated, target)]),
                 np.array([turned(v) for v in normal]), np.array([turned(v) for v in approach]),
                 push=np.array([turned(v) for v in push]))
