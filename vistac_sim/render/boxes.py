"""Exact pixel boxes of capsule outlines clipped to the image."""

from __future__ import annotations

import math

import numpy as np


def boxes_from_outlines(capsules_px, image_size: int) -> np.ndarray:
    """(n, 4) boxes (x, y, w, h) of each group of pixel capsules (p0, p1, radius) clipped to
    the image; an invisible group gets a zero box."""
    boxes = np.zeros((len(capsules_px), 4))
    for k, caps in enumerate(capsules_px):
        pts = [p for p0, p1, r in caps for p in clipped_points(p0, p1, r, image_size)]
        if pts:
            xs, ys = [p[0] for p in pts], [p[1] for p in pts]
            boxes[k] = [min(xs), min(ys), max(xs) - min(xs), max(ys) - min(ys)]
    return boxes


def clipped_points(p0, p1, radius: float, size: float) -> list[tuple[float, float]]:
    """Points of (capsule p0-p1 widened by `radius`) within [0, size]^2 whose box is exactly the
    box of that intersection (empty if they do not meet).

    The extreme points of a convex set clipped to a square are extreme points of the set, points
    where its boundary crosses the square's sides, or corners of the square. Candidates: the
    axis-extreme points of both end circles, every crossing of the square's side lines with both
    circles and both flat sides, and the four corners; kept if they lie in the capsule and in the
    square (points inside both do not widen the box, so over-collecting is harmless). Plain
    floats: a few dozen candidates are cheaper in Python than in small numpy arrays.
    """
    x0, y0, x1, y1, r = float(p0[0]), float(p0[1]), float(p1[0]), float(p1[1]), float(radius)
    ext = [(x0 + r, y0), (x0 - r, y0), (x0, y0 + r), (x0, y0 - r),
           (x1 + r, y1), (x1 - r, y1), (x1, y1 + r), (x1, y1 - r)]
    lo_x, hi_x = min(x0, x1) - r, max(x0, x1) + r
    lo_y, hi_y = min(y0, y1) - r, max(y0, y1) + r
    if lo_x >= 0 and lo_y >= 0 and hi_x <= size and hi_y <= size:  # wholly inside
        return ext
    if lo_x > size or lo_y > size or hi_x < 0 or hi_y < 0:  # wholly outside
        return []
    # Corners the capsule's box holds; crossings only of the side lines its box straddles (the
    # boundary meets no other side line, or touches it at an extreme point already listed).
    cand = ext + [(cx, cy) for cx in (0.0, size) for cy in (0.0, size)
                  if lo_x <= cx <= hi_x and lo_y <= cy <= hi_y]
    dx, dy = x1 - x0, y1 - y0
    length = math.hypot(dx, dy)
    nx, ny = (-dy / length * r, dx / length * r) if length > 0 else (0.0, 0.0)
    for line in (0.0, size):
        cross_x, cross_y = lo_x < line < hi_x, lo_y < line < hi_y
        for cx, cy in ((x0, y0), (x1, y1)):  # end circles crossing x = line and y = line
            h2 = r * r - (line - cx) ** 2
            if cross_x and h2 >= 0:
                h = math.sqrt(h2)
                cand += [(line, cy + h), (line, cy - h)]
            h2 = r * r - (line - cy) ** 2
            if cross_y and h2 >= 0:
                h = math.sqrt(h2)
                cand += [(cx + h, line), (cx - h, line)]
        if length > 0:  # flat sides (s + t d, t in [0, 1]) crossing the lines
            for sx, sy in ((x0 + nx, y0 + ny), (x0 - nx, y0 - ny)):
                if dx and cross_x:
                    t = min(max((line - sx) / dx, 0.0), 1.0)
                    cand.append((sx + t * dx, sy + t * dy))
                if dy and cross_y:
                    t = min(max((line - sy) / dy, 0.0), 1.0)
                    cand.append((sx + t * dx, sy + t * dy))
    eps = 1e-9 * max(size, 1.0)
    dd = dx * dx + dy * dy
    keep = []
    for px, py in cand:
        if not (-eps <= px <= size + eps and -eps <= py <= size + eps):
            continue
        t = min(max(((px - x0) * dx + (py - y0) * dy) / dd, 0.0), 1.0) if dd > 0 else 0.0
        if (px - x0 - t * dx) ** 2 + (py - y0 - t * dy) ** 2 <= (r + eps) ** 2:
            keep.append((min(max(px, 0.0), size), min(max(py, 0.0), size)))
    return keep
