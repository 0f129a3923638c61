"""A tiny synthetic dataset in the `vistac generate` layout, for the vistac_learn tests.

It stands in for the simulator: a polygonal object on a grey table, index finger (green) and
thumb (red) drawn as capsules pressed against two different edges, the sensor-frame labels
computed from the same geometry as the dataset format describes (its frames and layout,
docs/dataset-format.md). Forces are the surface normal plus a bounded tangential (friction-like)
part, so the geometric baseline has a known answer (`normal_f_*`) and the labels a known spread.
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pandas as pd

from vistac.dataset import FORMAT_VERSION
from vistac.dataset.schema import PIXEL_CENTRE

TABLE = (0.81, 0.81, 0.81)
INDEX_RGB = (0.0, 0.85, 0.0)
THUMB_RGB = (0.9, 0.0, 0.0)
TIP_R = 0.0095  # m
SHAFT = 0.045  # m drawn behind the tip centre
EXTENT = 0.16  # m across the image
FINGERS = ("index", "thumb")


def _to_px(xy: np.ndarray, cam: np.ndarray, ppm: float, size: int) -> np.ndarray:
    """World xy (.., 2) -> pixel (u, v), image y down, centres at integers (OpenCV's), so
    drawn where the simulator draws (`vistac.dataset.schema.PIXEL_CENTRE`)."""
    u = (xy[..., 0] - cam[0]) * ppm + size / 2 - PIXEL_CENTRE
    v = (cam[1] - xy[..., 1]) * ppm + size / 2 - PIXEL_CENTRE
    return np.stack([u, v], axis=-1)


def _sensor_axes(a: np.ndarray, finger: str) -> tuple[np.ndarray, np.ndarray]:
    """(y, z) sensor axes in world xy for approach direction `a` (unit, world xy)."""
    y = np.array([-a[1], a[0]]) if finger == "index" else np.array([a[1], -a[0]])
    return y, a


def _draw_capsule(img: np.ndarray, p0: np.ndarray, p1: np.ndarray, r: float, rgb) -> np.ndarray:
    """Draw a filled capsule (pixel endpoints, radius in pixels); return its boolean mask."""
    mask = np.zeros(img.shape[:2], np.uint8)
    shift = 4
    f = 1 << shift
    a = tuple(int(round(c * f)) for c in p0)
    b = tuple(int(round(c * f)) for c in p1)
    ri = int(round(r * f))
    cv2.circle(mask, a, ri, 255, -1, cv2.LINE_8, shift)
    cv2.circle(mask, b, ri, 255, -1, cv2.LINE_8, shift)
    d = (p1 - p0) / max(np.linalg.norm(p1 - p0), 1e-9)
    n = np.array([-d[1], d[0]]) * r
    quad = np.array([p0 + n, p1 + n, p1 - n, p0 - n]) * f
    cv2.fillConvexPoly(mask, np.round(quad).astype(np.int32), 255, cv2.LINE_8, shift)
    m = mask > 0
    img[m] = np.round(np.array(rgb) * 255).astype(np.uint8)
    return m


def make_dataset(
    out: Path,
    n: int = 12,
    repeats: int = 3,
    size: int = 96,
    seed: int = 0,
    noise: float = 0.05,
    friction: float = 0.3,
    splits: tuple[float, float, float] = (0.5, 0.25, 0.25),
    complete: bool = True,
) -> Path:
    """Write a small dataset directory and return its path.

    Args:
        out: Folder to create (must not exist or be empty).
        n: Number of configurations.
        repeats: Presses per configuration.
        size: Image side in pixels.
        seed: Seed of everything drawn.
        noise: Relative std of the per-press force noise.
        friction: Largest tangential force as a fraction of the normal force.
        splits: Train / val / test fractions, assigned by configuration.
        complete: Value of the manifest's `complete` flag.

    Returns:
        The dataset directory.
    """
    rng = np.random.default_rng(seed)
    out = Path(out)
    (out / "images").mkdir(parents=True, exist_ok=True)
    ppm = size / EXTENT
    n_train = int(round(splits[0] * n))
    n_val = int(round(splits[1] * n))
    split_of = ["train"] * n_train + ["val"] * n_val + ["test"] * (n - n_train - n_val)
    rows, presses = [], []
    for cid in range(n):
        sides = int(rng.integers(3, 7))
        radius = rng.uniform(0.022, 0.035)
        yaw = rng.uniform(0, 2 * np.pi)
        centre = rng.uniform(-0.01, 0.01, size=2)
        ang = yaw + np.arange(sides) * 2 * np.pi / sides
        verts = centre + radius * np.stack([np.cos(ang), np.sin(ang)], axis=1)
        cam = centre + rng.uniform(-0.005, 0.005, size=2)
        img = np.empty((size, size, 3), np.uint8)
        img[:] = np.round(np.array(TABLE) * 255).astype(np.uint8)
        colour = rng.uniform(0.1, 0.5, size=3)
        colour[1] = min(colour[1], 0.3)
        poly = _to_px(verts, cam, ppm, size)
        cv2.fillPoly(img, [np.round(poly * 16).astype(np.int32)],
                     tuple(int(c) for c in np.round(colour * 255)), cv2.LINE_8, 4)
        e_index = int(rng.integers(sides))
        e_thumb = (e_index + sides // 2) % sides
        row = {
            "config_id": cid, "object_id": f"poly{sides}_{cid % 4}",
            "object_family": "prism", "image": f"{cid:06d}.png", "split": split_of[cid],
            "object_x": centre[0], "object_y": centre[1], "object_yaw": yaw,
            "camera_x": cam[0], "camera_y": cam[1], "px_per_m": ppm,
        }
        forces = np.zeros((repeats, 2, 3))
        for fi, (finger, edge, rgb) in enumerate(
            zip(FINGERS, (e_index, e_thumb), (INDEX_RGB, THUMB_RGB), strict=True)
        ):
            p0, p1 = verts[edge], verts[(edge + 1) % sides]
            t = rng.uniform(0.35, 0.65)
            contact = p0 + t * (p1 - p0)
            tangent = (p1 - p0) / np.linalg.norm(p1 - p0)
            normal = np.array([tangent[1], -tangent[0]])  # outward for CCW vertices
            spread = np.deg2rad(rng.uniform(-20, 20))
            c, s = np.cos(spread), np.sin(spread)
            a = -np.array([c * normal[0] - s * normal[1], s * normal[0] + c * normal[1]])
            tip = contact + normal * TIP_R
            back = tip - a * SHAFT
            mask = _draw_capsule(
                img, _to_px(tip, cam, ppm, size), _to_px(back, cam, ppm, size), TIP_R * ppm, rgb
            )
            vs, us = np.nonzero(mask)
            y_ax, z_ax = _sensor_axes(a, finger)
            n_sensor = np.array([0.0, normal @ y_ax, normal @ z_ax])
            mu = rng.uniform(-friction, friction)
            f_clean = 2.0 * (np.array([0.0, tangent @ y_ax, tangent @ z_ax]) * mu + n_sensor)
            row |= {
                f"target_{finger}_x": contact[0], f"target_{finger}_y": contact[1],
                f"approach_{finger}_x": a[0], f"approach_{finger}_y": a[1],
                f"tip_{finger}_x": tip[0], f"tip_{finger}_y": tip[1],
                f"bbox_{finger}_x": float(us.min()), f"bbox_{finger}_y": float(vs.min()),
                f"bbox_{finger}_w": float(us.max() - us.min() + 1),
                f"bbox_{finger}_h": float(vs.max() - vs.min() + 1),
            }
            for k, ax in enumerate("xyz"):
                row[f"force_clean_{finger}_{ax}"] = f_clean[k]
                row[f"normal_{finger}_{ax}"] = n_sensor[k]
            mag = np.linalg.norm(f_clean)
            forces[:, fi] = f_clean + rng.normal(0, noise * mag, size=(repeats, 3))
        rows.append(row)
        cv2.imwrite(str(out / "images" / row["image"]), cv2.cvtColor(img, cv2.COLOR_RGB2BGR))
        for k in range(repeats):
            p = {"config_id": cid, "repeat": k}
            for fi, finger in enumerate(FINGERS):
                for j, ax in enumerate("xyz"):
                    p[f"force_{finger}_{ax}"] = forces[k, fi, j]
                yz = forces[k, fi, 1:]
                r = yz / max(np.linalg.norm(yz), 1e-12)
                p[f"r_y_{finger}"], p[f"r_z_{finger}"] = r
            presses.append(p)
    pd.DataFrame(rows).to_parquet(out / "configs.parquet", index=False)
    pd.DataFrame(presses).to_parquet(out / "presses.parquet", index=False)
    manifest = {
        "format_version": FORMAT_VERSION,
        "complete": complete,
        "seed": seed,
        "config": {
            "n": n, "repeats": repeats, "seed": seed,
            "render": {"image_size": size, "view_extent": EXTENT, "table_rgb": list(TABLE),
                       "index_rgb": list(INDEX_RGB), "thumb_rgb": list(THUMB_RGB)},
            "effects": {"noise": noise},
        },
        "counts": {"configs": n, "presses": n * repeats},
    }
    (out / "manifest.json").write_text(json.dumps(manifest, indent=2))
    return out
