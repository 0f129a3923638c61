"""Grasp sampling: object pose, contact targets on the top-view outline, approach directions.

The hand closes along its own direction, not along the surface normals: the index target is
drawn on the object's outline at fingertip height and the closing axis within
`closing_spread_deg` of its inward normal; the index is pushed along it and the thumb back along
it, on the outline where that axis leaves the object, so the thumb's push-to-normal angle is
whatever the shape gives there (up to `max_push_angle_deg`). Each finger's own axis (its sensor
frame, drawn in the image) points within `approach_spread_deg` of its target's inward normal. The
whole finger (tip and shaft) must fit beside the object in its start pose, and the two fingers
must not overlap. What cannot be met is a `RejectedSample`.

Friction: a push outside the friction cone (half-angle atan(friction)) makes the pad slip until
its force lies on the cone's edge, which the press allows (the label is then the slipped force).
Without friction there is no edge to stop at, and such draws mostly end with a force off the
surface normal. So where the cone, widened by the check's tolerance (`cone_tolerance_deg`), is
narrower than `closing_spread_deg`, grasps are antipodal pairs within it: the closing axis is
drawn within the cone of the index's normal and the thumb's target must lie where the surface
normal is within the cone of the axis (`OutlineSampler.antipodal`). At the default friction 0.8
the cone (41.7 degrees) is wider than the closing spread (20), so this never applies and the draws
are those of before.

Grasps are drawn against the collision geometry that MuJoCo simulates: the outline is the section
of the object's convex collision pieces at the press height. For an object whose walls are not
vertical (a mesh) the pieces are also sliced at several heights across the tip: the outline is
where the tip first touches any of these slices, and a finger fits only if it keeps clear of each
slice by the tip's width at that height, so that no start penetrates.
"""

from __future__ import annotations

import bisect
import math
from typing import TYPE_CHECKING

import numpy as np
import shapely
from shapely.geometry import Polygon
from shapely.ops import unary_union

from vistac.dataset import FINGERS
from vistac_sim.hand.grasp import Grasp, cap_starts, to_world
from vistac_sim.objects.decomposition import pieces_section
from vistac_sim.objects.outlines import boundary_arrays
from vistac_sim.physics.checks import RejectedSample

if TYPE_CHECKING:
    from vistac_sim.generate.config import GenerateCfg
    from vistac_sim.objects.library import BuiltObject

# Heights across the tip (fractions of its radius above and below the axis) where the collision
# pieces of a mesh are sliced for the "finger fits" check.
CLEARANCE_LEVELS = (-0.95, -0.85, -0.7, -0.5, -0.25, 0.25, 0.5, 0.7, 0.85, 0.95)
ANTIPODAL_TRIES = 200
"""Index targets tried per draw for an antipodal pair (geometry only, ~30 us each)."""
REACHABLE_TRIES = 20
"""Antipodal pairs tried per draw for one whose fingers fit (~0.1 ms each)."""


def cone_limit_deg(friction: float, tolerance_deg: float) -> float:
    """Half-angle of the friction cone widened by the physical check's tolerance, degrees."""
    return math.degrees(math.atan(friction)) + tolerance_deg


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
        p0, p1, normals, cum = boundary_arrays(section)
        # the outline's segments as columns, for the far crossing (vectorised over segments)
        self._edge = tuple(np.ascontiguousarray((p1 - p0).T))
        self._p0x, self._p0y = np.ascontiguousarray(p0.T)
        # and as Python floats (immutable: shared by every draw): a draw works on one or two
        # points, where NumPy's per-call overhead would cost more than the arithmetic
        self._outline = tuple(tuple(map(tuple, a.tolist())) for a in (p0, p1, normals)) + (
            tuple(cum.tolist()),)
        self.keep_out = ((section, cfg.hand.tip_radius), *clearance)
        for geom, _ in self.keep_out:
            shapely.prepare(geom)
        cone = cone_limit_deg(cfg.physics.friction, cfg.physics.cone_tolerance_deg)
        self.antipodal_deg = cone if cone < cfg.grasp.closing_spread_deg else None
        """Pushes within this many degrees of both normals (antipodal pairs), or None: the
        friction cone is wider than the configured spreads."""

    @classmethod
    def of(cls, obj: BuiltObject, cfg: GenerateCfg) -> OutlineSampler:
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

    def _point(self, rng: np.random.Generator) -> tuple[list[float], tuple[float, ...]]:
        """A point drawn uniformly along the outline, and the outward normal there."""
        p0, p1, normals, cum = self._outline
        s = rng.uniform(0, cum[-1])
        seg = min(bisect.bisect_right(cum, s), len(cum) - 1)
        start = cum[seg - 1] if seg > 0 else 0.0
        t = (s - start) / (cum[seg] - start)
        a, b = p0[seg], p1[seg]
        return [a[0] * (1 - t) + b[0] * t, a[1] * (1 - t) + b[1] * t], normals[seg]

    @staticmethod
    def _turned(rng: np.random.Generator, normal,
                spread_deg: float) -> list[float]:
        """A unit direction within `spread_deg` (uniform) of the inward `normal`."""
        spread = math.radians(spread_deg)
        ang = rng.uniform(-spread, spread)
        c, s = math.cos(ang), math.sin(ang)
        ix, iy = -normal[0], -normal[1]
        return [c * ix - s * iy, s * ix + c * iy]

    def finger_axes(self, start, approach) -> np.ndarray:
        """Top-view axes (LineStrings) of both whole fingers (tip + shaft), each with its front
        cap centre at `start` (2, 2) and pointing along `approach` (2, 2).

        A finger's footprint is its segment widened by the tip radius (the widest part).
        """
        h = self.cfg.hand
        length = 2 * h.tip_half_length + h.shaft_length + h.shaft_radius
        return shapely.linestrings([[s, [s[0] - a[0] * length, s[1] - a[1] * length]]
                                    for s, a in zip(start, approach, strict=True)])

    def check(self, local: Grasp) -> None:
        """Check a grasp given in the object frame (yaw 0, at the origin).

        Raises:
            RejectedSample: "unreachable" (a finger would start inside the object) or
                "fingers_overlap".
        """
        h = self.cfg.hand
        self._check_axes(local.start(h.tip_radius, h.standoff).tolist(), local.approach.tolist())

    def _check_axes(self, start: list, approach: list) -> None:
        """`check` for the fingers' start points and axes, (2, 2) each."""
        h = self.cfg.hand
        axes = self.finger_axes(start, approach)
        inside = np.zeros(2, bool)
        for geom, width in self.keep_out:
            inside |= shapely.dwithin(geom, axes, width)
        for name, hit in zip(FINGERS, inside, strict=True):
            if hit:
                raise RejectedSample("unreachable", f"{name} finger would start inside the object")
        if shapely.dwithin(axes[0], axes[1], 2 * h.tip_radius):
            raise RejectedSample("fingers_overlap", "thumb and index would overlap")

    def far_crossing(self, point: list[float],
                     direction: list[float]) -> tuple[list[float], tuple[float, ...]]:
        """Where the line from `point` along `direction` last crosses the outline, and the
        outline's outward normal there (the thumb's target on the closing axis).

        Raises:
            RejectedSample: "no_opposing_thumb" when the line leaves no outline beyond `point`.
        """
        ex, ey = self._edge
        dx, dy = direction
        wx, wy = self._p0x - point[0], self._p0y - point[1]
        denom = dx * ey - dy * ex
        ok = np.abs(denom) > 1e-12  # not parallel (no division by zero below)
        denom = np.where(ok, denom, 1.0)
        t = (wx * ey - wy * ex) / denom
        u = (wx * dy - wy * dx) / denom
        hit = ok & (u >= 0) & (u <= 1) & (t > 1e-9)
        if not hit.any():
            raise RejectedSample("no_opposing_thumb", "the closing axis leaves no far side")
        k = int(np.argmax(np.where(hit, t, -np.inf)))
        tk = float(t[k])
        return [point[0] + tk * dx, point[1] + tk * dy], self._outline[2][k]

    def antipodal(self, rng: np.random.Generator, limit_deg: float):
        """An antipodal pair: index target and normal, closing axis within `limit_deg` of the
        index's inward normal, thumb target and normal within `limit_deg` of the axis; tried at
        up to `ANTIPODAL_TRIES` index targets.

        Returns:
            (index point, index normal, closing axis, thumb point, thumb normal).

        Raises:
            RejectedSample: "no_opposing_thumb" when no try gave a pair.
        """
        for _ in range(ANTIPODAL_TRIES):
            p_i, n_i = self._point(rng)
            close = self._turned(rng, n_i, limit_deg)
            try:
                p_t, n_t = self.far_crossing(p_i, close)
            except RejectedSample:
                continue
            if _off_deg(close, n_t) <= min(limit_deg, self.cfg.grasp.max_push_angle_deg):
                return p_i, n_i, close, p_t, n_t
        raise RejectedSample("no_opposing_thumb", f"no antipodal pair within {limit_deg:.1f} deg "
                             f"in {ANTIPODAL_TRIES} index targets")

    def sample(self, rng: np.random.Generator) -> Grasp:
        """Draw one grasp in world coordinates.

        Raises:
            RejectedSample: "unreachable" (a finger would start inside the object),
                "no_opposing_thumb" (the thumb's surface is too far off the closing axis),
                "fingers_overlap".
        """
        g, h = self.cfg.grasp, self.cfg.hand
        yaw = float(rng.uniform(-np.pi, np.pi))
        xy = rng.uniform(-0.01, 0.01, 2)
        if self.antipodal_deg is not None:
            return to_world(yaw, xy, *self._reachable_antipodal(rng))
        p_i, n_i = self._point(rng)
        close = self._turned(rng, n_i, g.closing_spread_deg)  # the index's push
        p_t, n_t = self.far_crossing(p_i, close)
        off = _off_deg(close, n_t)
        if off > g.max_push_angle_deg:
            raise RejectedSample("no_opposing_thumb", f"the thumb's surface is {off:.0f} deg "
                                 f"off the closing axis (limit {g.max_push_angle_deg:g})")
        target, normal = [p_i, p_t], [n_i, n_t]
        approach = [self._turned(rng, n, g.approach_spread_deg) for n in normal]
        push = [close, [-close[0], -close[1]]]
        self._check_axes(cap_starts(target, normal, push, h.tip_radius, h.standoff), approach)
        return to_world(yaw, xy, target, normal, approach, push)

    def _reachable_antipodal(self, rng: np.random.Generator) -> tuple[list, ...]:
        """An antipodal pair whose fingers fit (`sample` in a narrow friction cone): a pair on
        which a finger would start inside the object, or the fingers overlap, is drawn again, up
        to `REACHABLE_TRIES` pairs, before the draw is rejected (where antipodal pairs are rare,
        as on a scan or a knot, the fingers cannot reach most of them).

        Returns:
            targets, normals, approaches and pushes (2 x 2 nested lists each, object frame).
        """
        for _ in range(REACHABLE_TRIES - 1):
            try:
                return self._antipodal_fit(rng)
            except RejectedSample as exc:
                if exc.reason not in ("unreachable", "fingers_overlap"):
                    raise
        return self._antipodal_fit(rng)

    def _antipodal_fit(self, rng: np.random.Generator) -> tuple[list, ...]:
        """One antipodal pair with its finger axes, checked (`_reachable_antipodal`)."""
        g, h = self.cfg.grasp, self.cfg.hand
        p_i, n_i, close, p_t, n_t = self.antipodal(rng, self.antipodal_deg)
        target, normal = [p_i, p_t], [n_i, n_t]
        approach = [self._turned(rng, n, g.approach_spread_deg) for n in normal]
        push = [close, [-close[0], -close[1]]]
        self._check_axes(cap_starts(target, normal, push, h.tip_radius, h.standoff), approach)
        return target, normal, approach, push


def _off_deg(axis, normal) -> float:
    """Degrees between the closing axis and the outward normal where it leaves the object."""
    return math.degrees(math.acos(min(max(axis[0] * normal[0] + axis[1] * normal[1], -1.0), 1.0)))
