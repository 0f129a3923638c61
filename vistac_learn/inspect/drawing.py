"""Drawing on an image: force arrows at the fingertips, press cones, mask outlines, captions and
tile grids (OpenCV on RGB uint8 arrays; nothing here reads or writes files)."""

from __future__ import annotations

import cv2
import numpy as np

from vistac.dataset.schema import MASK_VALUES

MEAN_RGB = (0, 0, 0)
"""The mean label's arrow."""
PRESS_RGB = (255, 140, 0)
"""Each press's direction (together: the cone)."""
PRED_RGB = (30, 90, 255)
"""A model's prediction (`vistac inspect RUN`)."""
MASK_RGB = {"object": (40, 40, 255), "index": (0, 90, 0), "thumb": (120, 0, 0)}
"""Outline colours of the mask classes (`--masks` datasets)."""
ARROW_FRACTION = 0.22
"""Arrow length as a share of the image width."""
SHIFT = 4  # OpenCV's fixed-point bits: sub-pixel endpoints


def _pt(p: np.ndarray) -> tuple[int, int]:
    return int(round(p[0] * (1 << SHIFT))), int(round(p[1] * (1 << SHIFT)))


def line(img: np.ndarray, start: np.ndarray, direction: np.ndarray, length: float, rgb,
         width: int = 1, head: bool = False) -> None:
    """Draw (in place) a segment, or an arrow with `head`, from `start` along `direction`."""
    end = np.asarray(start, float) + length * np.asarray(direction, float)
    if head:
        cv2.arrowedLine(img, _pt(start), _pt(end), rgb, width, cv2.LINE_AA, SHIFT, 0.3)
    else:
        cv2.line(img, _pt(start), _pt(end), rgb, width, cv2.LINE_AA, SHIFT)


def draw_finger(img: np.ndarray, tip: np.ndarray, mean: np.ndarray | None,
                presses: np.ndarray, pred: np.ndarray | None = None) -> None:
    """The cone (one thin line per press), the mean label's arrow and, if given, a predicted
    direction's arrow, all from the fingertip centre `tip` (image pixels)."""
    length = ARROW_FRACTION * img.shape[1]
    width = max(1, round(img.shape[1] / 120))
    for d in presses:  # longer than the arrow: the cone fans out beyond its head
        line(img, tip, d, 1.4 * length, PRESS_RGB, 1)
    if mean is not None:
        line(img, tip, mean, length, MEAN_RGB, width + (2 if pred is not None else 1), head=True)
    if pred is not None:  # thinner, on top: the label's black shows around a close prediction
        line(img, tip, pred, length, PRED_RGB, width, head=True)
    cv2.circle(img, _pt(tip), 2 << SHIFT, MEAN_RGB, -1, cv2.LINE_AA, SHIFT)


def outline_mask(img: np.ndarray, mask: np.ndarray) -> None:
    """Outline (in place) each class of a mask (docs/dataset-format.md) on its image."""
    if mask.shape[:2] != img.shape[:2]:
        return
    for name, rgb in MASK_RGB.items():
        region = (mask == MASK_VALUES[name]).astype(np.uint8)
        contours, _ = cv2.findContours(region, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
        cv2.drawContours(img, contours, -1, rgb, 1, cv2.LINE_8)


def caption(img: np.ndarray, text: str, height: int = 16, rgb=(255, 255, 255)) -> np.ndarray:
    """The image with a caption strip below it."""
    strip = np.full((height, img.shape[1], 3), 40, np.uint8)
    cv2.putText(strip, text, (3, height - 4), cv2.FONT_HERSHEY_SIMPLEX, height / 38, rgb, 1,
                cv2.LINE_AA)
    return np.concatenate([img, strip], axis=0)


def grid(tiles: list[np.ndarray], columns: int, gap: int = 4) -> np.ndarray:
    """The tiles (same size) in rows of `columns`, on white."""
    h, w = tiles[0].shape[:2]
    rows = -(-len(tiles) // columns)
    cols = min(columns, len(tiles))
    out = np.full((rows * (h + gap) + gap, cols * (w + gap) + gap, 3), 255, np.uint8)
    for i, t in enumerate(tiles):
        r, c = divmod(i, columns)
        out[gap + r * (h + gap):gap + r * (h + gap) + h, gap + c * (w + gap):
            gap + c * (w + gap) + w] = t
    return out


def resized(img: np.ndarray, size: int) -> np.ndarray:
    """A square tile of side `size` (area interpolation)."""
    if img.shape[0] == size and img.shape[1] == size:
        return img
    return cv2.resize(img, (size, size), interpolation=cv2.INTER_AREA)


def write_png(path, rgb: np.ndarray) -> None:
    """Write an RGB image as a compact PNG (atomically)."""
    from vistac.dataset.files import atomic_write_bytes

    ok, buf = cv2.imencode(".png", np.ascontiguousarray(rgb[:, :, ::-1]),
                           [cv2.IMWRITE_PNG_COMPRESSION, 9])
    if not ok:
        raise OSError(f"{path}: PNG encoding failed")
    atomic_write_bytes(path, buf.tobytes())
