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

from vistac_sim.render.view import Finish

NOISE_MARGIN = 128  # the noise bank is this many pixels larger than the image per side


@functools.lru_cache(maxsize=4)
def noise_bank(size: int) -> np.ndarray:
    """(size + NOISE_MARGIN)^2 x 3 float32 unit normals, the same in every process."""
    bank = np.random.default_rng(0x5E45).standard_normal(
        (size + NOISE_MARGIN, size + NOISE_MARGIN, 3), dtype=np.float32)
    bank.setflags(write=False)
    return bank


def apply_finish(rgb: np.ndarray, finish: Finish) -> np.ndarray:
    """The frame as the phone's camera would deliver it (uint8, same shape)."""
    img = rgb.astype(np.float32)
    if finish.gain != (1.0, 1.0, 1.0):
        img *= np.asarray(finish.gain, np.float32)
    if finish.defocus > 0:
        img = cv2.GaussianBlur(img, (0, 0), finish.defocus)
    length, angle = finish.motion
    if length >= 1.0:
        img = cv2.filter2D(img, -1, motion_kernel(length, angle))
    read, shot = finish.noise
    if read > 0 or shot > 0:
        h, w = img.shape[:2]
        r, c = finish.noise_at
        unit = noise_bank(max(h, w))[r:r + h, c:c + w]
        img += unit * np.sqrt(read * read + shot * np.clip(img, 0, None))
    out = np.clip(img + 0.5, 0, 255).astype(np.uint8)  # round half up (values are >= 0)
    if finish.jpeg:
        ok, buf = cv2.imencode(".jpg", out[..., ::-1], [cv2.IMWRITE_JPEG_QUALITY, finish.jpeg])
        out = cv2.imdecode(buf, cv2.IMREAD_COLOR)[..., ::-1]
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
