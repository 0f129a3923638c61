"""The variant images of a dataset, computed once and cached.

`variant_images` computes a variant for every configuration and angle of a rotation set and
caches the uint8 array (N, R, C, S, S) as one ``.npy`` file under the cache folder, keyed by a
hash of (variant settings, size, the angle array, dataset fingerprint, pipeline version); it is
computed once and memory-mapped afterwards, never recomputed per epoch.
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import asdict
from pathlib import Path

import numpy as np
from tqdm import tqdm

from vistac.dataset import FINGERS, DatasetTables
from vistac.errors import UserError
from vistac_learn.data.pairs import RotationCfg
from vistac_learn.data.variants import (
    PIPELINE_VERSION,
    VariantCfg,
    auto_canny,
    read_rgb,
    render_variant,
)


def cache_key(tables: DatasetTables, cfg: VariantCfg, angles: np.ndarray) -> str:
    """Hex key of a cached variant array (settings, angles, dataset fingerprint, version)."""
    h = hashlib.sha256()
    h.update(json.dumps({"v": PIPELINE_VERSION, **asdict(cfg)}, sort_keys=True).encode())
    h.update(np.ascontiguousarray(angles, dtype=np.float64).tobytes())
    h.update(tables.fingerprint().encode())
    return h.hexdigest()[:20]


def default_cache_dir(tables: DatasetTables) -> Path:
    """The cache folder used when none is given: ``<dataset>/cache/variants``."""
    return tables.root / "cache" / "variants"


def variant_images(
    tables: DatasetTables,
    cfg: VariantCfg,
    rotations: RotationCfg,
    cache_dir: str | Path | None = None,
    progress: bool = False,
) -> np.ndarray:
    """The variant of every configuration at every angle, from the cache or computed once.

    Args:
        tables: The dataset.
        cfg: The variant.
        rotations: The rotation set.
        cache_dir: Cache folder (default `default_cache_dir`).
        progress: Show a progress bar while computing.

    Returns:
        Read-only memory-mapped uint8 array (N, R, C, S, S) over all configuration rows.

    Raises:
        UserError: An unreadable image, missing boxes, an unwritable cache folder.
    """
    angles = rotations.angles(tables.configs["config_id"].to_numpy())
    key = cache_key(tables, cfg, angles)
    folder = Path(cache_dir) if cache_dir is not None else default_cache_dir(tables)
    path = folder / f"{cfg.name}-{cfg.size}-{key}.npy"
    if path.exists():
        return np.load(path, mmap_mode="r")
    for f in cfg.region_fingers:
        if not tables.has_boxes(f):
            raise UserError(
                f"{tables.root / 'configs.parquet'}: variant {cfg.name} needs columns "
                f"bbox_{f}_x|y|w|h with finite values for every configuration"
            )
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UserError(
            f"{folder}: cannot create the variant cache ({exc}); choose one with --cache-dir"
        ) from exc
    n, r = angles.shape
    tmp = path.with_suffix(f".tmp{os.getpid()}.npy")
    arr = np.lib.format.open_memmap(
        tmp, mode="w+", dtype=np.uint8, shape=(n, r, cfg.channels, cfg.size, cfg.size)
    )
    table_rgb = tables.table_rgb
    it = range(n)
    if progress:
        it = tqdm(it, desc=f"variant {cfg.name} {cfg.size}px", unit="img", leave=False)
    for row in it:
        image = read_rgb(tables.image_path(row))
        boxes = {f: tables.box(row, f) for f in FINGERS}
        edges = auto_canny(image, cfg.canny_low_ratio, cfg.canny_floor) if (
            cfg.mode == "edge") else None
        for k in range(r):
            arr[row, k] = render_variant(image, boxes, angles[row, k], cfg, table_rgb, edges)
    arr.flush()
    del arr
    os.replace(tmp, path)
    meta = {"variant": asdict(cfg), "rotations": asdict(rotations), "shape": [n, r],
            "dataset": str(tables.root), "fingerprint": tables.fingerprint(), "key": key}
    path.with_suffix(".json").write_text(json.dumps(meta, indent=2))
    return np.load(path, mmap_mode="r")
