"""Image-space camera effects on a rendered frame (`Finish`): exposure and white balance,
defocus and motion blur, sensor noise, JPEG.

All are whole-array OpenCV/NumPy operations on the (H, W, 3) uint8 frame. The sensor noise reads
a crop of a fixed bank of unit normals made once per process and image size (drawing 150 k
normals per image would cost more than the render), so a finish is replayed exactly from its
parameters.
"""

from __future__ import annotations

import functools

import cv2
import numpy as np

from vistac_sim.render.shot import Finish

NOISE_MARGIN = 128  # the noise bank is this many pixels larger than the image per side


@functools.lru_cache(maxsize=4)
def noise_bank(size: int) -> np.ndarray:
    """(size + NOISE_MARGIN)^2 x 3 float32 unit normals, the same in every process."""
    bank = np.random.default_rng(0x5E45).standard_normal(
        (size + NOISE_MARGIN, size + NOISE_MARGIN, 3), dtype=np.float32)
    bank.setflags(write=False)
    return bank


def apply_finish(rgb: np.ndarray, finish: Finish) -> np.ndarray:
    """The frame as the phone's camera would deliver it (uint8, same shape).

    Whole-image OpenCV operations on uint8 (saturating, rounding to nearest): the gain as a
    look-up table per channel, the blurs, then the noise, whose std per pixel comes from a
    float look-up table of the pixel's value.
    """
    out = np.ascontiguousarray(rgb)
    if finish.gain != (1.0, 1.0, 1.0):
        levels = np.arange(256, dtype=np.float32)
        lut = np.clip(np.rint(levels[:, None] * np.asarray(finish.gain, np.float32)), 0, 255)
        out = cv2.LUT(out, lut.astype(np.uint8).reshape(256, 1, 3))
    if finish.defocus > 0:
        out = cv2.GaussianBlur(out, (0, 0), finish.defocus)
    length, angle = finish.motion
    if length >= 1.0:
        out = cv2.filter2D(out, -1, motion_kernel(length, angle))
    read, shot = finish.noise
    if read > 0 or shot > 0:
        h, w = out.shape[:2]
        r, c = finish.noise_at
        unit = noise_bank(max(h, w))[r:r + h, c:c + w]
        std = np.sqrt(read * read + shot * np.arange(256, dtype=np.float32)).astype(np.float32)
        sigma = cv2.LUT(out, np.repeat(std[:, None], 3, axis=1).reshape(256, 1, 3))
        out = cv2.add(out, cv2.multiply(unit, sigma), dtype=cv2.CV_8U)  # unit: a view, no copy
    if finish.jpeg:  # channels swapped by OpenCV itself (a numpy [..., ::-1] view costs a copy)
        bgr = cv2.cvtColor(out, cv2.COLOR_RGB2BGR)
        ok, buf = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, finish.jpeg])
        out = cv2.imdecode(buf, cv2.IMREAD_COLOR_RGB)
    return np.ascontiguousarray(out)


def motion_kernel(length: float, angle: float) -> np.ndarray:
    """Normalised line kernel of `length` px along `angle` (rad, image x towards image y)."""
    k = int(np.ceil(length)) | 1  # odd side
    kernel = np.zeros((k, k), np.float32)
    c = (k - 1) / 2
    d = np.array([np.cos(angle), np.sin(angle)]) * (length - 1) / 2
    cv2.line(kernel, (int(round(16 * (c - d[0]))), int(round(16 * (c - d[1])))),
             (int(round(16 * (c + d[0]))), int(round(16 * (c + d[1])))), 1.0, 1, cv2.LINE_AA,
             shift=4)
    return kernel / kernel.sum()
