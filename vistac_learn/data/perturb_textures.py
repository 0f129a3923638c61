"""The textures the learner's `table` and `object` perturbations paint with
(`vistac_learn.data.perturb`): a random crop of a scikit-image photograph
(`vistac.textures.PERTURB_PHOTOS`, tinted when grey) or a procedural kind (wood grain, woven
cloth, paper, stripes, noise, a printed label), each an (h, w, 3) float32 RGB image in [0, 1]
drawn from the `numpy.random.Generator` passed in.
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import cv2
import numpy as np

from vistac.textures import PERTURB_PHOTOS, photo

PHOTOS = tuple(sorted({name for names in PERTURB_PHOTOS.values() for name in names}))


@functools.cache
def _photo(name: str) -> np.ndarray:
    """A scikit-image sample photograph (`vistac.textures.photo`) as (H, W, 3) float32 RGB,
    0-255."""
    return photo(name).astype(np.float32)


def _smooth_noise(h: int, w: int, cell: float, rng: np.random.Generator) -> np.ndarray:
    """Zero-mean, unit-scale noise varying over about `cell` pixels."""
    gh, gw = int(h / cell) + 3, int(w / cell) + 3
    small = rng.standard_normal((gh, gw)).astype(np.float32)
    return cv2.resize(small, (w + 2 * int(cell), h + 2 * int(cell)),
                      interpolation=cv2.INTER_CUBIC)[int(cell):int(cell) + h,
                                                     int(cell):int(cell) + w]


def coords(h: int, w: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Pixel coordinates rotated by a random angle (along, across)."""
    a = rng.uniform(0, np.pi)
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    return xx * np.cos(a) + yy * np.sin(a), -xx * np.sin(a) + yy * np.cos(a)


def _colour(rng: np.random.Generator, lo: float = 40, hi: float = 230) -> np.ndarray:
    return rng.uniform(lo, hi, 3).astype(np.float32)


def photo_texture(h: int, w: int, rng: np.random.Generator, names=PHOTOS) -> np.ndarray:
    """A random crop of a sample photograph, resized, flipped and tinted if grey."""
    name = names[int(rng.integers(len(names)))]
    src = _photo(name)
    sh, sw = src.shape[:2]
    side = int(min(sh, sw) * rng.uniform(0.35, 1.0))
    y0, x0 = int(rng.integers(0, sh - side + 1)), int(rng.integers(0, sw - side + 1))
    tex = cv2.resize(src[y0:y0 + side, x0:x0 + side], (w, h), interpolation=cv2.INTER_AREA)
    tex = np.rot90(tex, int(rng.integers(4)))
    if rng.random() < 0.5:
        tex = tex[:, ::-1]
    tex = np.ascontiguousarray(tex)
    if np.ptp(src.reshape(-1, 3).mean(axis=0)) < 1e-3:  # a grey photograph: tint it
        tex = tex * (_colour(rng, 120, 255) / 255.0)
    return tex


def wood_texture(h: int, w: int, rng: np.random.Generator) -> np.ndarray:
    """Wood grain: bent rings of light and dark brown."""
    _, v = coords(h, w, rng)
    period = rng.uniform(6, 16)
    bend = 0.6 * _smooth_noise(h, w, 70, rng) + 0.08 * _smooth_noise(h, w, 6, rng)
    t = 0.5 + 0.5 * np.sin(2 * np.pi * (v / period + bend))[..., None] ** 3
    light = np.array([205, 160, 110], np.float32) * rng.uniform(0.8, 1.15)
    dark = np.array([130, 85, 50], np.float32) * rng.uniform(0.7, 1.1)
    grain = 6.0 * rng.standard_normal((h, w, 1)).astype(np.float32)
    return dark + t * (light - dark) + grain


def cloth_texture(h: int, w: int, rng: np.random.Generator) -> np.ndarray:
    """Woven cloth: a fine two-way weave over a random colour, with folds."""
    u, v = coords(h, w, rng)
    f = 2 * np.pi / rng.uniform(2.5, 5.0)
    weave = np.sin(u * f) * np.sin(v * f)
    folds = 0.12 * _smooth_noise(h, w, 50, rng)
    shade = (1 + 0.12 * weave + folds)[..., None]
    return _colour(rng, 60, 220) * shade + 5.0 * rng.standard_normal((h, w, 1)).astype(
        np.float32)


def paper_texture(h: int, w: int, rng: np.random.Generator) -> np.ndarray:
    """Paper: near white, mottled, with faint fibres."""
    base = np.array([238, 234, 222], np.float32) * rng.uniform(0.85, 1.0)
    mottle = 6.0 * _smooth_noise(h, w, 25, rng) + 3.0 * _smooth_noise(h, w, 4, rng)
    img = base + mottle[..., None]
    for _ in range(int(rng.integers(5, 15))):
        p = rng.uniform(0, [w, h])
        q = p + rng.uniform(-25, 25, 2)
        cv2.line(img, tuple(int(x) for x in p), tuple(int(x) for x in q),
                 (base * 0.93).tolist(), 1, cv2.LINE_AA)
    return img


def stripes_texture(h: int, w: int, rng: np.random.Generator) -> np.ndarray:
    """Stripes of two random colours."""
    u, _ = coords(h, w, rng)
    t = (np.sin(2 * np.pi * u / rng.uniform(4, 14)) > 0)[..., None]
    return np.where(t, _colour(rng), _colour(rng))


def noise_texture(h: int, w: int, rng: np.random.Generator) -> np.ndarray:
    """Speckled random colour (plastic, stone)."""
    n = _smooth_noise(h, w, rng.uniform(1.5, 6), rng)[..., None]
    return _colour(rng) * (1 + 0.18 * n)


def label_texture(h: int, w: int, rng: np.random.Generator) -> np.ndarray:
    """A printed label: a coloured ground with blocks and lines of 'text'."""
    img = np.empty((h, w, 3), np.float32)
    img[:] = _colour(rng, 80, 250)
    for _ in range(int(rng.integers(3, 9))):
        x, y = int(rng.integers(0, w)), int(rng.integers(0, h))
        cv2.rectangle(img, (x, y), (x + int(rng.integers(8, 60)), y + int(rng.integers(3, 20))),
                      _colour(rng, 0, 255).tolist(), -1)
    for y in range(int(rng.integers(0, 8)), h, int(rng.integers(6, 12))):
        x = int(rng.integers(0, w // 2))
        cv2.line(img, (x, y), (x + int(rng.integers(10, w)), y), _colour(rng, 0, 90).tolist(),
                 1)
    return img


TABLE_TEXTURES: dict[str, Callable] = {
    "photo": functools.partial(photo_texture, names=PERTURB_PHOTOS["table"]),
    "wood": wood_texture, "cloth": cloth_texture, "paper": paper_texture,
}
OBJECT_TEXTURES: dict[str, Callable] = {
    "photo": functools.partial(photo_texture, names=PERTURB_PHOTOS["object"]),
    "wood": wood_texture, "stripes": stripes_texture, "noise": noise_texture,
    "label": label_texture,
}


def pick(table: dict[str, Callable], rng: np.random.Generator) -> Callable:
    """One texture maker of `table`, drawn uniformly."""
    return list(table.values())[int(rng.integers(len(table)))]
