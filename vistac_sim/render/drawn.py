"""Fingers drawn by hand into the photograph (`DrawnStyle`), and the dataset's masks.

A drawn finger is a filled polygon over the finished frame: the finger's outline in the image
(`vistac_sim.render.outlines.finger_shapes`), widened or narrowed, as capsules or one tapered
shape, with or without an outline and anti-aliasing. The finger's box and its mask pixels are
those of the same polygons (the outline included), so boxes, masks and pixels agree.
"""

from __future__ import annotations

import cv2
import numpy as np

from vistac.dataset.schema import MASK_VALUES, PIXEL_CENTRE
from vistac_sim.render.outlines import many_finger_shapes, polygons_box
from vistac_sim.render.shot import DrawnStyle, Shot

SHIFT = 4  # sub-pixel bits of the polygon vertices handed to OpenCV


def drawn_shapes(capsules: list[np.ndarray], shot: Shot) -> list[tuple[list, list]]:
    """Per finger: (polygons of its outline colour, polygons of its fill), in pixels.

    Without an outline the two lists are the same polygons.
    """
    d = shot.drawn
    jobs = [(caps, width, 0.0, d.taper) for caps, width in zip(capsules, d.width, strict=True)]
    if d.outline:
        jobs += [(caps, width, d.outline / 2, d.taper) for caps, width, _, _ in jobs]
    shapes = many_finger_shapes(jobs, shot)
    n = len(capsules)
    return [(shapes[n + k] if d.outline else shapes[k], shapes[k]) for k in range(n)]


def drawn_boxes(shapes: list[tuple[list, list]], size: int) -> np.ndarray:
    """(2, 4) boxes of the drawn fingers (their outlines included), clipped to the image."""
    return np.stack([polygons_box(outer, size) for outer, _ in shapes])


def draw_fingers(rgb: np.ndarray, shapes: list[tuple[list, list]], style: DrawnStyle
                 ) -> np.ndarray:
    """The frame with the fingers drawn over it (index first, then thumb)."""
    img = np.ascontiguousarray(rgb).copy()
    line = cv2.LINE_AA if style.antialias else cv2.LINE_8
    outline = tuple(float(v) * 255 for v in style.outline_rgb)
    for (outer, fill), rgb_f in zip(shapes, style.rgb, strict=True):
        if style.outline:
            _fill(img, outer, outline, line)
        _fill(img, fill, tuple(float(v) * 255 for v in rgb_f), line)
    return img


def fill_mask(mask: np.ndarray, shapes: list[tuple[list, list]]) -> np.ndarray:
    """A label image with the drawn fingers' pixels set to their mask values (hard edges)."""
    for (outer, _), value in zip(shapes, (MASK_VALUES["index"], MASK_VALUES["thumb"]),
                                 strict=True):
        _fill(mask, outer, value, cv2.LINE_8)
    return mask


def _fill(img: np.ndarray, polys: list[np.ndarray], colour, line: int) -> None:
    """Fill each convex polygon (one at a time: overlaps stay filled), vertices in OpenCV's
    fixed point (pixel centres at integers; ours at + `PIXEL_CENTRE`)."""
    for p in polys:
        fixed = np.round((np.asarray(p, float) - PIXEL_CENTRE) * (1 << SHIFT)).astype(np.int32)
        cv2.fillConvexPoly(img, fixed, colour, line, SHIFT)
