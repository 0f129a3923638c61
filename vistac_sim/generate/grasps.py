"""Grasp sampling: object pose, contact targets on the top-view outline, approach directions.

The hand closes along its own direction, not along the surface normals: the index target is
drawn on the object's outline at fingertip height and the closing axis within
`closing_spread_deg` of its inward normal; the index is pushed along it and the thumb back along
it, on the outline where that axis leaves the object, so the thumb's push-to-normal angle is
whatever the shape gives there (up to `max_push_angle_deg`). Each finger's own axis (its sensor
frame, drawn in the image) points within `approach_spread_deg` of its target's inward normal. The
whole finger (tip and shaft) must fit beside the object in its start pose, and the two fingers
must not overlap. What cannot be met is a `RejectedSample`.

Grasps are drawn against the collision geometry that MuJoCo simulates: the outline is the section
of the object's convex collision pieces at the press height. For an object whose walls are not
vertical (a mesh) the pieces are also sliced at several heights across the tip: the outline is
where the tip first touches any of these slices, and a finger fits only if it keeps clear of each
slice by the tip's width at that height, so that no start penetrates.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import shapely
from shapely.geometry import Polygon
from shapely.ops import unary_union

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
        # Where the tip's centre first touches the pieces (the section at the press height and
        # those above and below, each widened by the tip's width there), less the tip radius:
        # the outline a bulging object presents to the pad.
        reach = unary_union([obj.section.buffer(r, quad_segs=8)]
                            + [g.buffer(w, quad_segs=8) for g, w in levels]).buffer(-r)
        if reach.geom_type != "Polygon":
            reach = max(getattr(reach, "geoms", [obj.section]), key=lambda g: g.area)
        outline = reach if reach.area >= obj.section.area else obj.section
        return cls(shapely.Polygon(outline.exterior), cfg, ((obj.section, r), *levels))

    def _points(self, rng: np.random.Generator, k: int) -> tuple[np.ndarray, np.ndarray]:
        s = rng.uniform(0, self.cum[-1], k)
        seg = np.searchsorted(self.cum, s, side="right").clip(max=len(self.cum) - 1)
        start = np.where(seg > 0, self.cum[seg - 1], 0.0)
        t = ((s - start) / (self.cum[seg] - start))[:, None]
        return self.p0[seg] * (1 - t) + self.p1[seg] * t, self.normals[seg]

    def _approach(self, rng: np.random.Generator, normals: np.ndarray,
                  spread_deg: float) -> np.ndarray:
        """Unit directions within `spread_deg` (uniform) of the inward `normals`."""
        spread = np.radians(spread_deg)
        ang = rng.uniform(-spread, spread, len(normals))
        c, s = np.cos(ang), np.sin(ang)
        inward = -normals
        return np.stack([c * inward[:, 0] - s * inward[:, 1], s * inward[:, 0] + c * inward[:, 1]],
                        axis=1)

    def finger_axes(self, start: np.ndarray, approach: np.ndarray) -> np.ndarray:
        """Top-view axes (LineStrings) of both whole fingers (tip + shaft), each with its front
        cap centre at `start` (2, 2) and pointing along `approach` (2, 2).

        A finger's footprint is its segment widened by the tip radius (the widest part).
        """
        h = self.cfg.hand
        back = start - approach * (2 * h.tip_half_length + h.shaft_length + h.shaft_radius)
        return shapely.linestrings(np.stack([start, back], axis=1))

    def check(self, local: Grasp) -> None:
        """Check a grasp given in the object frame (yaw 0, at the origin).

        Raises:
            RejectedSample: "unreachable" (a finger would start inside the object) or
                "fingers_overlap".
        """
        h = self.cfg.hand
        axes = self.finger_axes(local.start(h.tip_radius, h.standoff), local.approach)
        inside = np.zeros(2, bool)
        for geom, width in self.keep_out:
            inside |= shapely.dwithin(geom, axes, width)
        for name, hit in zip(FINGERS, inside, strict=True):
            if hit:
                raise RejectedSample("unreachable", f"{name} finger would start inside the object")
        if shapely.dwithin(axes[0], axes[1], 2 * h.tip_radius):
            raise RejectedSample("fingers_overlap", "thumb and index would overlap")

    def far_crossing(self, point: np.ndarray,
                     direction: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Where the line from `point` along `direction` last crosses the outline, and the
        outline's outward normal there (the thumb's target on the closing axis).

        Raises:
            RejectedSample: "no_opposing_thumb" when the line leaves no outline beyond `point`.
        """
        e = self.p1 - self.p0
        w = self.p0 - point
        denom = direction[0] * e[:, 1] - direction[1] * e[:, 0]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (w[:, 0] * e[:, 1] - w[:, 1] * e[:, 0]) / denom
            u = (w[:, 0] * direction[1] - w[:, 1] * direction[0]) / denom
        hit = (np.abs(denom) > 1e-12) & (u >= 0) & (u <= 1) & (t > 1e-9)
        if not hit.any():
            raise RejectedSample("no_opposing_thumb", "the closing axis leaves no far side")
        k = int(np.argmax(np.where(hit, t, -np.inf)))
        return point + t[k] * direction, self.normals[k]

    def sample(self, rng: np.random.Generator) -> Grasp:
        """Draw one grasp in world coordinates.

        Raises:
            RejectedSample: "unreachable" (a finger would start inside the object),
                "no_opposing_thumb" (the thumb's surface is too far off the closing axis),
                "fingers_overlap".
        """
        g = self.cfg.grasp
        yaw = float(rng.uniform(-np.pi, np.pi))
        xy = rng.uniform(-0.01, 0.01, 2)
        p_i, n_i = self._points(rng, 1)
        close = self._approach(rng, n_i, g.closing_spread_deg)[0]  # the index's push
        p_t, n_t = self.far_crossing(p_i[0], close)
        off = np.degrees(np.arccos(np.clip(close @ n_t, -1.0, 1.0)))
        if off > g.max_push_angle_deg:
            raise RejectedSample("no_opposing_thumb", f"the thumb's surface is {off:.0f} deg off "
                                 f"the closing axis (limit {g.max_push_angle_deg:g})")
        normals = np.stack([n_i[0], n_t])
        local = Grasp(xy, yaw, np.stack([p_i[0], p_t]), normals,
                      self._approach(rng, normals, g.approach_spread_deg),
                      push=np.stack([close, -close]))
        self.check(local)
        return to_world(local)
