"""Appearance perturbations of rendered top views, toward photographs (registered by name).

A clean render has four flat colours: the table, one object colour, the index overlay and the
thumb overlay. `segment` recovers those four regions exactly from the colours (or a dataset's
masks can be passed as `Scene.labels`), and each perturbation below changes how one thing
*looks* while the geometry, and so every label, stays what the simulator made. Axes:

- ``table``: the table replaced by a texture: a photograph from scikit-image's sample data
  (`vistac.textures.PERTURB_PHOTOS`: the photographs of both packages are listed there), or
  procedural wood grain, woven cloth or paper (`vistac_learn.data.perturb_textures`);
- ``object``: the object textured (photograph, wood, stripes, noise or a printed label), with
  shading across it and a specular highlight;
- ``overlay``: the finger overlays restyled as a person would draw them: hue within +-20 deg of
  the nominal colour, saturation 0.55-1, value 0.6-1, 1-2 px thinner or wider, a dark outline
  or none, anti-aliased or hard edges (each finger drawn independently);
- ``light``: a linear shading gradient (+-10-30 %) in a random direction, exposure 0.75-1.1 and a
  colour-temperature shift of the white balance (red/blue gains +-15 %), over the whole image;
- ``tilt``: the view of a camera tilted 2-5 deg about a random axis in the table plane, rolled
  by up to 3 deg (a homography K R K^-1 of a 65 deg field of view, centre kept in place; border
  pixels replicated, as a photograph shows more of the same);
- ``camera``: Gaussian or motion blur, sensor noise (sigma 2-8 of 255) and JPEG at quality 30-85;
- ``all``: every axis in the order a photograph makes them (table, object, overlay, light,
  tilt, camera).

Train-time augmentation (`random_axes`) applies the region axes (table, object, overlay) only
to flat renders (`is_flat_render`); a photograph gets the image-level axes alone.

`perturb(name, rgb, scene, rng)` returns the new image and the homography that maps pixel
coordinates of the clean render to the perturbed one (identity but for ``tilt``), so that
positions in the image (the fingertips) can be compared with the simulator's truth. Every draw
comes from the `numpy.random.Generator` passed in.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np

from vistac.dataset import FINGERS
from vistac.errors import UserError
from vistac_learn.data.perturb_textures import OBJECT_TEXTURES, TABLE_TEXTURES, coords, pick

TABLE, OBJECT = 0, 1
FINGER_LABEL = {f: 2 + i for i, f in enumerate(FINGERS)}  # index 2, thumb 3 (the masks' codes)


@dataclass(frozen=True)
class Scene:
    """What the perturbations know of a clean render.

    Attributes:
        labels: (H, W) uint8 region of each pixel: `TABLE`, `OBJECT` or `FINGER_LABEL[f]`.
        finger_rgb: Nominal overlay colour of each finger, [0, 1].
    """

    labels: np.ndarray
    finger_rgb: dict[str, tuple[float, float, float]]


@dataclass(frozen=True)
class Perturbed:
    """A perturbed image and the homography from clean to perturbed pixel coordinates."""

    rgb: np.ndarray
    homography: np.ndarray


def segment(rgb: np.ndarray, finger_rgb: dict[str, tuple], table_rgb: tuple,
            tol: int = 12) -> np.ndarray:
    """Region labels of a clean render from its flat colours (see `Scene.labels`).

    A pixel within `tol` (per channel, 0-255) of the table colour is table; one whose colour is
    a finger's up to brightness (the overlays are drawn at full value, the manifest may give the
    finger's darker body colour) is that finger; everything else is object.
    """
    if rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.dtype != np.uint8:
        raise UserError(f"expected an (H, W, 3) uint8 RGB image, got {rgb.shape} {rgb.dtype}")
    img = rgb.astype(np.float32)
    top = img.max(axis=2, keepdims=True)
    chroma = img / np.maximum(top, 1.0)
    labels = np.full(rgb.shape[:2], OBJECT, np.uint8)
    ref = 255.0 * np.asarray(table_rgb, np.float32)
    labels[(np.abs(img - ref) <= tol).all(axis=2)] = TABLE
    for f, c in finger_rgb.items():
        c = np.asarray(c, np.float32)
        near = (np.abs(chroma - c / max(float(c.max()), 1e-6)) <= tol / 255.0).all(axis=2)
        labels[near & (top[..., 0] >= 128)] = FINGER_LABEL[f]
    return labels


# ---------------------------------------------------------------------------------- the axes
def table_axis(img: np.ndarray, scene: Scene, rng: np.random.Generator) -> np.ndarray:
    """The table's pixels replaced by a photograph or a procedural texture."""
    h, w = scene.labels.shape
    tex = pick(TABLE_TEXTURES, rng)(h, w, rng)
    sel = scene.labels == TABLE
    img[sel] = tex[sel]
    return img


def object_axis(img: np.ndarray, scene: Scene, rng: np.random.Generator) -> np.ndarray:
    """The object textured, shaded across and given a specular highlight."""
    sel = scene.labels == OBJECT
    if not sel.any():
        return img
    h, w = sel.shape
    tex = pick(OBJECT_TEXTURES, rng)(h, w, rng)
    vs, us = np.nonzero(sel)
    u, v = coords(h, w, rng)
    span = max(float(np.ptp(us)), float(np.ptp(vs)), 1.0)
    shade = 1.0 + rng.uniform(0.1, 0.35) * (u - u[sel].mean()) / span
    c = np.array([us.mean(), vs.mean()]) + rng.uniform(-0.3, 0.3, 2) * span
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    spec = rng.uniform(0, 70) * np.exp(-((xx - c[0]) ** 2 + (yy - c[1]) ** 2)
                                       / (2 * (0.15 * span) ** 2))
    img[sel] = (tex * shade[..., None] + spec[..., None])[sel]
    return img


def _hsv_rgb(h_deg: float, s: float, v: float) -> np.ndarray:
    px = np.array([[[h_deg / 2.0, s * 255, v * 255]]], np.float32).astype(np.uint8)
    return cv2.cvtColor(px, cv2.COLOR_HSV2RGB)[0, 0].astype(np.float32)


def _nominal_hue(rgb) -> float:
    r, g, b = (float(c) for c in rgb)
    return float(np.degrees(np.arctan2(np.sqrt(3) * (g - b), 2 * r - g - b)) % 360)


def overlay_axis(img: np.ndarray, scene: Scene, rng: np.random.Generator) -> np.ndarray:
    """Each finger overlay redrawn: colour, width, outline, edge softness."""
    base = img.copy()
    fingers = [f for f in scene.finger_rgb if (scene.labels == FINGER_LABEL[f]).any()]
    under = np.zeros(scene.labels.shape, np.uint8)
    for f in fingers:
        under |= (scene.labels == FINGER_LABEL[f]).astype(np.uint8)
    if not under.any():
        return img
    # the scene beneath the overlays, guessed from its surroundings
    clipped = np.clip(base, 0, 255).astype(np.uint8)
    ground = cv2.inpaint(clipped, cv2.dilate(under, np.ones((3, 3), np.uint8)), 3,
                         cv2.INPAINT_TELEA).astype(np.float32)
    img = np.where(under[..., None] > 0, ground, img)
    for f in fingers:
        m = (scene.labels == FINGER_LABEL[f]).astype(np.uint8)
        dw = int(rng.integers(-2, 3))
        k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * abs(dw) + 1, 2 * abs(dw) + 1))
        m = cv2.dilate(m, k) if dw > 0 else cv2.erode(m, k) if dw < 0 else m
        hue = (_nominal_hue(scene.finger_rgb[f]) + rng.uniform(-20, 20)) % 360
        colour = _hsv_rgb(hue, rng.uniform(0.55, 1.0), rng.uniform(0.6, 1.0))
        alpha = m.astype(np.float32)
        if rng.random() < 0.5:  # anti-aliased edge
            alpha = cv2.GaussianBlur(alpha, (0, 0), rng.uniform(0.5, 1.0))
        layer = np.empty_like(img)
        layer[:] = colour
        if rng.random() < 0.5:  # an outline, 1-2 px, dark or a darker shade
            width = int(rng.integers(1, 3))
            inner = cv2.erode(m, np.ones((2 * width + 1, 2 * width + 1), np.uint8))
            ring = (m > 0) & (inner == 0)
            layer[ring] = colour * rng.uniform(0.0, 0.5)
        img = img * (1 - alpha[..., None]) + layer * alpha[..., None]
    return img


def light_axis(img: np.ndarray, scene: Scene, rng: np.random.Generator) -> np.ndarray:
    """Shading gradient, exposure and white balance over the whole image."""
    h, w = img.shape[:2]
    u, _ = coords(h, w, rng)
    u = (u - u.mean()) / max(float(np.ptp(u)), 1.0)
    ramp = 1.0 + 2 * rng.uniform(0.1, 0.3) * u
    t = rng.uniform(-0.15, 0.15)
    gains = np.array([1 + t, 1 + rng.uniform(-0.03, 0.03), 1 - t], np.float32)
    return img * (rng.uniform(0.75, 1.1) * ramp)[..., None] * gains


def tilt_homography(w: int, h: int, rng: np.random.Generator) -> np.ndarray:
    """Homography of a camera tilted 2-5 deg about a random in-plane axis and rolled +-3 deg."""
    f = 0.5 * w / np.tan(np.radians(65.0) / 2)
    k = np.array([[f, 0, w / 2], [0, f, h / 2], [0, 0, 1]])
    tilt, dirn, roll = (np.radians(rng.uniform(2, 5)), rng.uniform(0, 2 * np.pi),
                        np.radians(rng.uniform(-3, 3)))
    axis = np.array([np.cos(dirn), np.sin(dirn), 0.0]) * tilt
    rot, _ = cv2.Rodrigues(axis)
    rz, _ = cv2.Rodrigues(np.array([0.0, 0.0, roll]))
    hom = k @ rz @ rot @ np.linalg.inv(k)
    c = hom @ np.array([w / 2, h / 2, 1.0])
    shift = np.array([[1, 0, w / 2 - c[0] / c[2]], [0, 1, h / 2 - c[1] / c[2]], [0, 0, 1]])
    return shift @ hom


def tilt_axis(img: np.ndarray, scene: Scene, rng: np.random.Generator
              ) -> tuple[np.ndarray, np.ndarray]:
    """The image seen by a slightly tilted camera; (image, homography)."""
    h, w = img.shape[:2]
    hom = tilt_homography(w, h, rng)
    out = cv2.warpPerspective(img, hom, (w, h), flags=cv2.INTER_LINEAR,
                              borderMode=cv2.BORDER_REPLICATE)
    return out, hom


def camera_axis(img: np.ndarray, scene: Scene, rng: np.random.Generator) -> np.ndarray:
    """Blur (defocus or motion), sensor noise and JPEG."""
    if rng.random() < 0.7:
        img = cv2.GaussianBlur(img, (0, 0), rng.uniform(0.4, 1.0))
    else:
        n = int(rng.integers(3, 6))
        kern = np.zeros((n, n), np.float32)
        kern[n // 2] = 1.0 / n
        rot = cv2.getRotationMatrix2D(((n - 1) / 2, (n - 1) / 2), rng.uniform(0, 180), 1.0)
        kern = cv2.warpAffine(kern, rot, (n, n))
        img = cv2.filter2D(img, -1, kern / max(float(kern.sum()), 1e-6))
    img = img + rng.uniform(2, 8) * rng.standard_normal(img.shape).astype(np.float32)
    q = int(rng.integers(30, 86))
    ok, buf = cv2.imencode(".jpg", np.clip(img[..., ::-1], 0, 255).astype(np.uint8),
                           [cv2.IMWRITE_JPEG_QUALITY, q])
    return cv2.imdecode(buf, cv2.IMREAD_COLOR)[..., ::-1].astype(np.float32)


AXES: dict[str, Callable] = {
    "table": table_axis, "object": object_axis, "overlay": overlay_axis,
    "light": light_axis, "tilt": tilt_axis, "camera": camera_axis,
}
PERTURBATIONS = (*AXES, "all")


def check_names(names) -> tuple[str, ...]:
    """Perturbation names, checked (``none`` and empty mean none)."""
    out = tuple(n for n in names if n and n != "none")
    bad = [n for n in out if n not in PERTURBATIONS]
    if bad:
        raise UserError(f"unknown perturbation {bad[0]!r}; choose from "
                        f"{', '.join(PERTURBATIONS)}")
    return out


def perturb(name: str, rgb: np.ndarray, scene: Scene, rng: np.random.Generator) -> Perturbed:
    """One perturbation (an axis or ``all``) of a clean render.

    Args:
        name: A name of `PERTURBATIONS`.
        rgb: (H, W, 3) uint8 clean render.
        scene: Its regions (`segment`) and overlay colours.
        rng: Source of every draw.

    Returns:
        The perturbed uint8 image and the clean-to-perturbed homography.
    """
    check_names([name])
    return perturb_axes(tuple(AXES) if name == "all" else (name,), rgb, scene, rng)


def perturb_axes(axes: tuple[str, ...], rgb: np.ndarray, scene: Scene,
                 rng: np.random.Generator) -> Perturbed:
    """Several axes applied in the order of `AXES` (see `perturb`)."""
    if scene.labels.shape != rgb.shape[:2]:
        raise UserError(f"labels {scene.labels.shape} do not match the image {rgb.shape[:2]}")
    img = rgb.astype(np.float32)
    hom = np.eye(3)
    for axis in (a for a in AXES if a in axes):
        res = AXES[axis](img, scene, rng)
        if isinstance(res, tuple):
            img, h = res
            hom = h @ hom
        else:
            img = res
    return Perturbed(np.clip(img + 0.5, 0, 255).astype(np.uint8), hom)


REGION_AXES = ("table", "object", "overlay")  # these need the regions of a flat render
FLAT_TABLE_SHARE = 0.1  # a flat render shows at least this share of bare table


def is_flat_render(labels: np.ndarray) -> bool:
    """Whether `segment`'s labels are those of a flat-colour render: at least
    `FLAT_TABLE_SHARE` of the pixels have the table's exact colour. A photograph (``--preset
    photo``, an ingested recording) has almost none: its regions cannot be read off its colours."""
    return bool((labels == TABLE).mean() >= FLAT_TABLE_SHARE)


def random_axes(rng: np.random.Generator, p: float = 0.5, flat: bool = True
                ) -> tuple[str, ...]:
    """A random set of axes (train-time augmentation): each with probability `p`, at least one.
    Not `flat` (a photograph): the image-level axes only (light, tilt, camera), drawn alike."""
    pick = tuple(a for a in AXES if rng.random() < p)
    pick = pick or (list(AXES)[int(rng.integers(len(AXES)))],)
    if flat:
        return pick
    image_axes = [a for a in AXES if a not in REGION_AXES]
    return tuple(a for a in pick if a in image_axes) or \
        (image_axes[int(rng.integers(len(image_axes)))],)


def map_points(hom: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """(N, 2) pixel positions (u, v) moved by a homography."""
    p = np.asarray(pts, float).reshape(-1, 2)
    q = np.concatenate([p, np.ones((len(p), 1))], axis=1) @ hom.T
    return q[:, :2] / q[:, 2:3]


def map_direction(hom: np.ndarray, at: np.ndarray, d: np.ndarray, step: float = 5.0
                  ) -> np.ndarray:
    """A unit direction `d` at point `at` moved by a homography (its local linear map)."""
    a, b = map_points(hom, np.stack([at, at + step * np.asarray(d, float)]))
    v = b - a
    return v / np.linalg.norm(v)
