"""The texture bank: procedural textures and photographs, made once per process.

Two banks of square RGB textures, keyed by kind: the object bank (wood grain, noise, stripes,
printed labels, photographs) and the table bank (wood, cloth, paper, photographs). Every texture
is a pure function of its kind and variant number (fixed seeds), so a dataset does not depend on
which process made it. Photographs are scikit-image's sample photographs of
`vistac.textures.BANK_PHOTOS` (the photographs of both packages are listed there) and, with
``--textures DIR``, the user's own images.

A scene that asks for textures gets the whole bank in its model (`vistac_sim.render.materials`);
a configuration only picks one texture, tint and scale (`vistac_sim.render.shot.Surface`).
"""

from __future__ import annotations

import functools
from pathlib import Path

import cv2
import numpy as np

from vistac.dataset.files import check_file
from vistac.errors import UserError
from vistac.textures import BANK_PHOTOS, cut, photo

SIZE = 256  # texels per side of every texture
VARIANTS = 3  # textures per procedural kind
OBJECT_KINDS = ("wood", "noise", "stripes", "label", "photo")
TABLE_KINDS = ("wood", "cloth", "paper", "photo")
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")


def bank(which: str, user_dir: str | None = None) -> dict[str, list[np.ndarray]]:
    """The object (``which="object"``) or table bank: kind -> (SIZE, SIZE, 3) uint8 textures.

    Raises:
        UserError: `user_dir` is not a folder or holds no readable image.
    """
    kinds = OBJECT_KINDS if which == "object" else TABLE_KINDS
    out = {k: [procedural(which, k, v) for v in range(VARIANTS)] for k in kinds if k != "photo"}
    out["photo"] = [*sample_photos(which), *user_textures(user_dir)]
    return out


@functools.lru_cache(maxsize=64)
def procedural(which: str, kind: str, variant: int) -> np.ndarray:
    """One procedural texture (read-only array): a pure function of its arguments."""
    rng = np.random.default_rng([sum(map(ord, which + kind)), variant, 0x7E47])
    make = {"wood": _wood, "noise": _noise, "stripes": _stripes, "label": _label,
            "cloth": _cloth, "paper": _paper}[kind]
    tex = np.clip(make(rng), 0, 255).astype(np.uint8)
    tex.setflags(write=False)
    return tex


@functools.lru_cache(maxsize=2)
def sample_photos(which: str) -> tuple[np.ndarray, ...]:
    """scikit-image's sample photographs of a bank (`BANK_PHOTOS`), cut and resized to SIZE."""
    return tuple(_square(cut(photo(name), crop)) for name, crop in BANK_PHOTOS[which])


@functools.lru_cache(maxsize=4)
def user_textures(folder: str | None) -> tuple[np.ndarray, ...]:
    """The images of a user's folder (sorted by name), centre-cropped and resized to SIZE.

    Raises:
        UserError: not a folder, or no readable image in it.
    """
    if folder is None:
        return ()
    path = Path(folder)
    if not path.is_dir():
        raise UserError(f"--textures {folder}: no such folder")
    out = []
    for f in sorted(p for p in path.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES):
        check_file(f, "--textures")  # a named pipe would block the read
        img = cv2.imread(str(f), cv2.IMREAD_COLOR)
        if img is not None:
            out.append(_square(img[..., ::-1]))
    if not out:
        raise UserError(f"--textures {folder}: no readable image ({', '.join(IMAGE_SUFFIXES)})")
    return tuple(out)


def _square(img: np.ndarray) -> np.ndarray:
    """An image centre-cropped to a square, resized to SIZE, as RGB uint8 (read-only)."""
    if img.ndim == 2:
        img = np.repeat(img[..., None], 3, axis=2)
    img = img[..., :3]
    h, w = img.shape[:2]
    s = min(h, w)
    img = img[(h - s) // 2:(h - s) // 2 + s, (w - s) // 2:(w - s) // 2 + s]
    out = np.ascontiguousarray(cv2.resize(img, (SIZE, SIZE), interpolation=cv2.INTER_AREA),
                               dtype=np.uint8)
    out.setflags(write=False)
    return out


# ------------------------------------------------------------------------ procedural kinds
def _smooth_noise(rng: np.random.Generator, cells: int, octaves: int = 4) -> np.ndarray:
    """(SIZE, SIZE) tileable fractal noise of unit std (bicubic upsampled lattices)."""
    out = np.zeros((SIZE, SIZE), np.float32)
    for o in range(octaves):
        n = cells * 2**o
        grid = rng.standard_normal((n, n)).astype(np.float32)
        tiled = np.tile(grid, (3, 3))  # wrap around: the texture repeats without seams
        up = cv2.resize(tiled, (3 * SIZE, 3 * SIZE), interpolation=cv2.INTER_CUBIC)
        out += up[SIZE:2 * SIZE, SIZE:2 * SIZE] * 0.5**o
    return (out - out.mean()) / max(float(out.std()), 1e-6)


def _colourise(grey: np.ndarray, dark, light) -> np.ndarray:
    """(SIZE, SIZE, 3) colours between `dark` and `light` (RGB 0-255) along grey in [0, 1]."""
    g = np.clip(grey, 0, 1)[..., None]
    return np.asarray(dark, np.float32) * (1 - g) + np.asarray(light, np.float32) * g


def _wood(rng: np.random.Generator) -> np.ndarray:
    y, x = np.mgrid[0:SIZE, 0:SIZE].astype(np.float32) / SIZE
    warp = _smooth_noise(rng, 2) * 0.08 + _smooth_noise(rng, 8, 2) * 0.01
    rings = int(rng.integers(6, 14))
    grain = 0.5 + 0.5 * np.sin(2 * np.pi * (rings * (y + warp) + 0.3 * np.sin(2 * np.pi * x)))
    grain = grain**3 * 0.7 + 0.15 * (_smooth_noise(rng, 32, 1) * 0.5 + 0.5)
    base = rng.uniform(0.8, 1.2)
    return _colourise(grain, np.array([120, 72, 38]) * base, np.array([214, 164, 110]) * base)


def _noise(rng: np.random.Generator) -> np.ndarray:
    g = _smooth_noise(rng, int(rng.integers(4, 16))) * 0.2 + 0.6
    hue = rng.uniform(60, 230, 3)
    return _colourise(g, hue * 0.4, hue)


def _stripes(rng: np.random.Generator) -> np.ndarray:
    y, x = np.mgrid[0:SIZE, 0:SIZE].astype(np.float32) / SIZE
    n = int(rng.integers(3, 10))
    angle = rng.choice([0.0, 0.5, 1.0])  # along x, diagonal, along y (tileable)
    phase = (x * angle + y * (1 - angle) if angle != 0.5 else x + y) * n
    band = (phase % 1.0) < rng.uniform(0.3, 0.7)
    c0, c1 = rng.uniform(30, 250, 3), rng.uniform(30, 250, 3)
    return np.where(band[..., None], c0, c1) + _smooth_noise(rng, 32, 1)[..., None] * 4


def _label(rng: np.random.Generator) -> np.ndarray:
    """A printed label: a coloured band with lines of 'text' and a logo disc."""
    bg = rng.uniform(150, 255, 3)
    img = np.empty((SIZE, SIZE, 3), np.uint8)
    img[:] = bg.astype(np.uint8)
    band = rng.uniform(20, 200, 3).astype(np.uint8)
    top = int(rng.integers(SIZE // 6, SIZE // 3))
    img[top:top + SIZE // 3] = band
    ink = tuple(float(v) for v in rng.uniform(0, 80, 3))
    for row in range(top + SIZE // 3 + 12, SIZE - 8, 14):  # lines of text-like dashes
        x = 10
        while x < SIZE - 20:
            w = int(rng.integers(4, 22))
            cv2.rectangle(img, (x, row), (min(x + w, SIZE - 10), row + 6), ink, -1)
            x += w + int(rng.integers(3, 7))
    c = tuple(float(v) for v in rng.uniform(0, 255, 3))
    cv2.circle(img, (int(rng.integers(40, SIZE - 40)), top + SIZE // 6), SIZE // 9, c, -1,
               cv2.LINE_AA)
    cv2.putText(img, "VISTAC", (12, top + SIZE // 4), cv2.FONT_HERSHEY_SIMPLEX, 1.2,
                tuple(255 - v for v in band.tolist()), 3, cv2.LINE_AA)
    return img.astype(np.float32)


def _cloth(rng: np.random.Generator) -> np.ndarray:
    y, x = np.mgrid[0:SIZE, 0:SIZE].astype(np.float32)
    period = float(SIZE // int(rng.integers(32, 64)))
    weave = (np.sin(2 * np.pi * x / period) * np.sin(2 * np.pi * y / period)) * 0.5 + 0.5
    g = 0.55 + 0.25 * weave + 0.1 * _smooth_noise(rng, 16, 2)
    colour = rng.uniform(80, 240, 3)
    return g[..., None] * colour


def _paper(rng: np.random.Generator) -> np.ndarray:
    g = 0.9 + 0.03 * _smooth_noise(rng, 32) + 0.02 * _smooth_noise(rng, 4, 2)
    tint = rng.uniform(225, 255, 3)
    return g[..., None] * tint
