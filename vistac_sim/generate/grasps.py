"""Grasp sampling: object pose, contact targets on the top-view outline, approach directions.

Targets lie on the object's outline at fingertip height. Each finger approaches within
`approach_spread_deg` of the inward surface normal; the thumb's approach opposes the index's by at
least `min_opposition_deg`; the whole finger (tip and shaft) must fit beside the object in its
start pose, and the two fingers must not overlap. What cannot be met is a `RejectedSample`.

Grasps are drawn against the collision geometry that MuJoCo simulates: the outline is the section
of the object's convex collision pieces at the press height, and a finger fits beside an object
whose walls are not vertical (a mesh) only if, at several heights across the tip, the pieces'
section keeps clear of the tip's width there, so that no start penetrates.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import shapely
from shapely.geometry import LineString, Polygon

from vistac.dataset import FINGERS
from vistac_sim.objects.decomposition import pieces_section
from vistac_sim.objects.outlines import boundary_arrays
from vistac_sim.physics.checks import RejectedSample
from vistac_sim.scene.grasp import Grasp, to_world

if TYPE_CHECKING:
    from vistac_sim.generate.config import GenerateCfg
    from vistac_sim.objects.library import SceneObject

# Heights across the tip (fractions of its radius above and below the axis) where the collision
# pieces of a mesh are sliced for the "finger fits" check.
CLEARANCE_LEVELS = (-0.95, -0.85, -0.7, -0.5, -0.25, 0.25, 0.5, 0.7, 0.85, 0.95)


class OutlineSampler:
    """Draws grasps on one object's outline (built once per object, used for every grasp)."""

    def __init__(self, section: Polygon, cfg: GenerateCfg,
                 clearance: tuple[tuple[object, float], ...] = ()):
        """Args:
            section: outline the targets lie on (at the press height).
            cfg: the run's config.
            clearance: more (geometry, width) pairs: the finger axis must stay farther than
                width from each geometry (sections of the pieces above and below the axis).
        """
        self.section = section
        self.cfg = cfg
        self.p0, self.p1, self.normals, self.cum = boundary_arrays(section)
        self.keep_out = ((section, cfg.hand.tip_radius), *clearance)
        for geom, _ in self.keep_out:
            shapely.prepare(geom)

    @classmethod
    def of(cls, obj: SceneObject, cfg: GenerateCfg) -> OutlineSampler:
        """The sampler of an object, with the clearance levels its collision pieces need.

        `cfg.hand.height` is the press height of this object.
        """
        if obj.vertical_walls:
            return cls(obj.section, cfg)
        r, z = cfg.hand.tip_radius, cfg.hand.height
        levels = []
        for f in CLEARANCE_LEVELS:
            geom = pieces_section(obj.pieces, z + f * r)
            if not geom.is_empty:
                levels.append((geom, r * float(np.sqrt(1 - f * f))))
        return cls(obj.section, cfg, tuple(levels))

    def _points(self, rng: np.random.Generator, k: int) -> tuple[np.ndarray, np.ndarray]:
        s = rng.uniform(0, self.cum[-1], k)
        seg = np.searchsorted(self.cum, s, side="right").clip(max=len(self.cum) - 1)
        start = np.where(seg > 0, self.cum[seg - 1], 0.0)
        t = ((s - start) / (self.cum[seg] - start))[:, None]
        return self.p0[seg] * (1 - t) + self.p1[seg] * t, self.normals[seg]

    def _approach(self, rng: np.random.Generator, normals: np.ndarray) -> np.ndarray:
        spread = np.radians(self.cfg.grasp.approach_spread_deg)
        ang = rng.uniform(-spread, spread, len(normals))
        c, s = np.cos(ang), np.sin(ang)
        inward = -normals
        return np.stack([c * inward[:, 0] - s * inward[:, 1], s * inward[:, 0] + c * inward[:, 1]],
                        axis=1)

    def finger_axis(self, start: np.ndarray, approach: np.ndarray) -> LineString:
        """Top-view axis of a whole finger (tip + shaft) with its front cap centre at `start`.

        The finger's footprint is this segment widened by the tip radius (the widest part).
        """
        h = self.cfg.hand
        back = start - approach * (2 * h.tip_half_length + h.shaft_length + h.shaft_radius)
        return LineString([start, back])

    def _inside(self, axis: LineString) -> bool:
        return any(shapely.dwithin(geom, axis, width) for geom, width in self.keep_out)

    def _overlap(self, a: LineString, b: LineString) -> bool:
        return bool(shapely.dwithin(a, b, 2 * self.cfg.hand.tip_radius))

    def check(self, local: Grasp) -> None:
        """Check a grasp given in the object frame (yaw 0, at the origin).

        Raises:
            RejectedSample: "unreachable" (a finger would start inside the object) or
                "fingers_overlap".
        """
        h = self.cfg.hand
        start = local.start(h.tip_radius, h.standoff)
        axes = [self.finger_axis(start[k], local.approach[k]) for k in range(2)]
        for name, axis in zip(FINGERS, axes, strict=True):
            if self._inside(axis):
                raise RejectedSample("unreachable", f"{name} finger would start inside the object")
        if self._overlap(*axes):
            raise RejectedSample("fingers_overlap", "thumb and index would overlap")

    def sample(self, rng: np.random.Generator, n_thumb_candidates: int = 24) -> Grasp:
        """Draw one grasp in world coordinates.

        Raises:
            RejectedSample: "unreachable" (a finger would start inside the object),
                "no_opposing_thumb" (no thumb target opposes the index), "fingers_overlap".
        """
        h = self.cfg.hand
        yaw = float(rng.uniform(-np.pi, np.pi))
        xy = rng.uniform(-0.01, 0.01, 2)
        p_i, n_i = self._points(rng, 1)
        a_i = self._approach(rng, n_i)
        s_i = p_i + n_i * h.tip_radius - a_i * h.standoff
        axis_i = self.finger_axis(s_i[0], a_i[0])
        if self._inside(axis_i):
            raise RejectedSample("unreachable", "index finger would start inside the object")
        p_t, n_t = self._points(rng, n_thumb_candidates)
        a_t = self._approach(rng, n_t)
        cos_min = np.cos(np.radians(self.cfg.grasp.min_opposition_deg))
        ok = (a_t @ a_i[0]) <= cos_min
        if not ok.any():
            raise RejectedSample("no_opposing_thumb", "no thumb target opposes the index finger")
        reason = RejectedSample("unreachable", "thumb would start inside the object")
        for k in np.flatnonzero(ok):
            s_t = p_t[k] + n_t[k] * h.tip_radius - a_t[k] * h.standoff
            axis_t = self.finger_axis(s_t, a_t[k])
            if self._inside(axis_t):
                continue
            if self._overlap(axis_t, axis_i):
                reason = RejectedSample("fingers_overlap", "thumb and index would overlap")
                continue
            local = Grasp(xy, yaw, np.concatenate([p_i, p_t[k:k + 1]]),
                          np.concatenate([n_i, n_t[k:k + 1]]), np.concatenate([a_i, a_t[k:k + 1]]))
            return to_world(local)
        raise reason
