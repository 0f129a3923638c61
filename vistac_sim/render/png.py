"""Deterministic PNG bytes of an RGB image."""

from __future__ import annotations

import struct
import zlib

import numpy as np


def encode_png(rgb: np.ndarray, level: int = 1) -> bytes:
    """Deterministic PNG bytes of an RGB image (H, W, 3) or a grey one (H, W) (8-bit, no
    filter, zlib `level`).

    Written with zlib directly: about twice as fast as OpenCV's encoder on these images.
    """
    h, w = rgb.shape[:2]
    channels = 1 if rgb.ndim == 2 else 3
    raw = np.zeros((h, w * channels + 1), np.uint8)  # each row: filter byte 0, then pixels
    raw[:, 1:] = rgb.reshape(h, -1)
    return b"".join([
        b"\x89PNG\r\n\x1a\n",
        _png_chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2 if channels == 3 else 0, 0, 0,
                                        0)),
        _png_chunk(b"IDAT", zlib.compress(raw.tobytes(), level)),
        _png_chunk(b"IEND", b""),
    ])


def _png_chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
