"""The study's image variants (docs/study.md section 4).

A variant name is ``<mode>-<region>``: mode ``color`` (RGB, 3 channels) or ``edge`` (Canny edges
of the base image, 1 channel); region ``base`` (the whole rotated image), ``crop`` (both finger
boxes), ``index`` or ``thumb`` (one finger's box). For example ``edge-index``.

Pipeline of one image at one angle (all whole-array OpenCV / NumPy):

1. ``edge`` only: Canny edges of the unrotated base image, thresholds chosen per image by the
   *gradient-Otsu rule* (`auto_canny`).
2. Rotate about the image centre by the angle (counter-clockwise as seen in the image), the
   uncovered corners filled with the background: table grey (the manifest's ``table_rgb``,
   default 0.81) for colour, black for edges.
3. Regions other than ``base``: rotate each finger box's four corners with the same affine map
   and take their axis-aligned bounding box; grow it by ``margin`` (fraction of the image side)
   on every side; fill everything outside the union of the grown boxes with the background; crop
   to the union.
4. Resize so that the long side equals the model's input size (area interpolation when shrinking,
   linear when enlarging) and pad to a square with the background, centred.

`vistac_learn.data.views.StudyView` renders a variant per sample, batch by batch.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from vistac.config import Config, param
from vistac.dataset import FINGERS
from vistac.dataset.files import check_file
from vistac.dataset.schema import TABLE_RGB
from vistac.errors import UserError

MODES = ("color", "edge")
REGIONS = ("base", "crop", "index", "thumb")
VARIANTS = tuple(f"{m}-{r}" for m in MODES for r in REGIONS)


@dataclass(frozen=True)
class VariantCfg(Config):
    """One image variant."""

    name: str = param("edge-index", choices=VARIANTS,
                      help="``<color|edge>-<base|crop|index|thumb>``")
    size: int = param(100, ge=8, help="side of the square output, px (the model's input size)")
    margin: float = param(0.05, ge=0, le=1, help="added round each finger box, as a fraction "
                          "of the source image side (0.05 of 227 px is 11 px, about one "
                          "fingertip radius at the default view)")
    canny_low_ratio: float = param(0.5, gt=0, le=1, help="low Canny threshold as a fraction "
                                   "of the high one")
    canny_floor: float = param(20.0, ge=0, help="smallest high threshold (gradient magnitude "
                               "units of an 8-bit image), so that a flat image yields no "
                               "edges rather than noise")

    @property
    def mode(self) -> str:
        """``color`` or ``edge``."""
        return self.name.split("-", 1)[0]

    @property
    def region(self) -> str:
        """``base``, ``crop``, ``index`` or ``thumb``."""
        return self.name.split("-", 1)[1]

    @property
    def channels(self) -> int:
        """Channels of the output image."""
        return 3 if self.mode == "color" else 1

    @property
    def region_fingers(self) -> tuple[str, ...]:
        """Finger boxes the region needs (none for ``base``)."""
        return {"base": (), "crop": FINGERS, "index": ("index",), "thumb": ("thumb",)}[
            self.region
        ]


def otsu_threshold(values: np.ndarray, bins: int = 256) -> float:
    """Otsu's threshold of a 1-D sample (maximises the between-class variance).

    Args:
        values: Finite values.
        bins: Histogram bins over [min, max].

    Returns:
        The threshold (a bin edge, or the middle of a run of empty bins that all split the
        values alike); the minimum if all values are equal.
    """
    lo, hi = float(values.min()), float(values.max())
    if hi <= lo:
        return lo
    hist, edges = np.histogram(values, bins=bins, range=(lo, hi))
    p = hist.astype(np.float64) / hist.sum()
    centres = 0.5 * (edges[:-1] + edges[1:])
    w0 = np.cumsum(p)
    mu = np.cumsum(p * centres)
    mu_t = mu[-1]
    w1 = 1 - w0
    with np.errstate(divide="ignore", invalid="ignore"):
        between = (mu_t * w0 - mu) ** 2 / (w0 * w1)
    between[~np.isfinite(between)] = -1
    # empty bins make a plateau of equal maxima (the same split of the values): take the
    # middle of the first plateau, so that rounding does not pick an arbitrary end of it
    ties = np.flatnonzero(between >= between.max() * (1 - 1e-9))
    run_end = ties[0]
    while run_end + 1 in ties:
        run_end += 1
    return float(0.5 * (edges[ties[0] + 1] + edges[run_end + 1]))


def auto_canny(rgb: np.ndarray, low_ratio: float = 0.5, floor: float = 20.0) -> np.ndarray:
    """Canny edges with per-image thresholds from the *gradient-Otsu rule*.

    Rule: blur the grey image with a 5 x 5 Gaussian (sigma 1); take the L2 Sobel (3 x 3)
    gradient magnitude G of every pixel, which is the quantity Canny thresholds; the high
    threshold is Otsu's threshold of G (it splits flat and textured pixels from edge pixels),
    at least `floor`; the low threshold is ``low_ratio`` times the high one. Canny then runs on
    the blurred image with the L2 gradient. Unlike the popular median-intensity rule, the
    thresholds are in gradient units, so a light object on the light table still gets edges.

    Args:
        rgb: (H, W, 3) or (H, W) uint8 image.
        low_ratio: Low threshold / high threshold.
        floor: Smallest high threshold.

    Returns:
        (H, W) uint8 edge image, 255 on edges.
    """
    grey = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY) if rgb.ndim == 3 else rgb
    blur = cv2.GaussianBlur(grey, (5, 5), 1.0)
    gx = cv2.Sobel(blur, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(blur, cv2.CV_32F, 0, 1, ksize=3)
    mag = cv2.magnitude(gx, gy)
    high = max(otsu_threshold(mag.ravel()), floor)
    return cv2.Canny(blur, low_ratio * high, high, apertureSize=3, L2gradient=True)


def rotation_matrix(angle_deg: float, width: int, height: int) -> np.ndarray:
    """2 x 3 affine map rotating by `angle_deg` (counter-clockwise on screen) about the centre."""
    return cv2.getRotationMatrix2D(((width - 1) / 2, (height - 1) / 2), float(angle_deg), 1.0)


def rotate_box(box: np.ndarray, m: np.ndarray) -> np.ndarray:
    """Axis-aligned bounding box (x, y, w, h) of a box (x, y, w, h) mapped by affine `m`.

    The box covers pixels x .. x+w-1, i.e. the continuous span [x - 0.5, x + w - 0.5] in the
    pixel-centre coordinates OpenCV's warps use; the result is in the same (x, y, w, h) form.
    """
    x, y, w, h = (float(v) for v in box)
    corners = np.array(
        [[x - 0.5, y - 0.5], [x + w - 0.5, y - 0.5], [x + w - 0.5, y + h - 0.5],
         [x - 0.5, y + h - 0.5]]
    )
    mapped = corners @ m[:, :2].T + m[:, 2]
    lo, hi = mapped.min(axis=0), mapped.max(axis=0)
    return np.array([lo[0] + 0.5, lo[1] + 0.5, hi[0] - lo[0], hi[1] - lo[1]])


def _fit_square(img: np.ndarray, size: int, bg) -> np.ndarray:
    """Resize so the long side is `size`, pad square (centred) with `bg`."""
    h, w = img.shape[:2]
    scale = size / max(h, w)
    nw, nh = max(1, round(w * scale)), max(1, round(h * scale))
    interp = cv2.INTER_AREA if scale < 1 else cv2.INTER_LINEAR
    small = cv2.resize(img, (nw, nh), interpolation=interp)
    top, left = (size - nh) // 2, (size - nw) // 2
    return cv2.copyMakeBorder(
        small, top, size - nh - top, left, size - nw - left, cv2.BORDER_CONSTANT, value=bg
    )


def render_variant(
    image: np.ndarray,
    boxes: dict[str, np.ndarray | None],
    angle_deg: float,
    cfg: VariantCfg,
    table_rgb=TABLE_RGB,
    edges: np.ndarray | None = None,
) -> np.ndarray:
    """One variant image of one base image at one angle.

    Args:
        image: (H, W, 3) uint8 RGB base image.
        boxes: Finger -> (x, y, w, h) of the drawn finger in the base image (pixels).
        angle_deg: Rotation angle.
        cfg: The variant.
        table_rgb: Background colour in [0, 1] for the colour fill.
        edges: Precomputed `auto_canny` of `image` (computed here if None and needed).

    Returns:
        (C, S, S) uint8.

    Raises:
        UserError: A box the region needs is missing.
    """
    if cfg.mode == "edge":
        src = auto_canny(image, cfg.canny_low_ratio, cfg.canny_floor) if edges is None else edges
        bg = 0
    else:
        src = image
        bg = tuple(int(round(c * 255)) for c in table_rgb)
    h, w = src.shape[:2]
    m = rotation_matrix(angle_deg, w, h)
    rot = cv2.warpAffine(
        src, m, (w, h), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=bg
    )
    if cfg.region != "base":
        pad = cfg.margin * max(h, w)
        spans = []
        for f in cfg.region_fingers:
            box = boxes.get(f)
            if box is None:
                raise UserError(f"variant {cfg.name} needs the {f} finger's box")
            x, y, bw, bh = rotate_box(box, m)
            x0 = int(np.clip(np.floor(x - pad), 0, w))
            y0 = int(np.clip(np.floor(y - pad), 0, h))
            x1 = int(np.clip(np.ceil(x + bw + pad), 0, w))
            y1 = int(np.clip(np.ceil(y + bh + pad), 0, h))
            spans.append((x0, y0, x1, y1))
        keep = np.zeros((h, w), bool)
        for x0, y0, x1, y1 in spans:
            keep[y0:y1, x0:x1] = True
        rot = np.where(keep[..., None] if rot.ndim == 3 else keep, rot, np.asarray(bg, rot.dtype))
        ux0, uy0 = min(s[0] for s in spans), min(s[1] for s in spans)
        ux1, uy1 = max(s[2] for s in spans), max(s[3] for s in spans)
        if ux1 <= ux0 or uy1 <= uy0:  # box rotated out of the image: an empty crop
            rot = np.full((1, 1) + rot.shape[2:], bg, rot.dtype)
        else:
            rot = rot[uy0:uy1, ux0:ux1]
    out = _fit_square(np.ascontiguousarray(rot), cfg.size, bg)
    return out[None] if out.ndim == 2 else np.transpose(out, (2, 0, 1)).copy()


def read_rgb(path: Path) -> np.ndarray:
    """Read an image file as (H, W, 3) uint8 RGB; UserError if unreadable (or not a regular
    file: a named pipe would block the read)."""
    check_file(path)
    bgr = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if bgr is None:
        raise UserError(f"{path}: missing or not a readable image")
    return cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
