"""Honest references beside every evaluation of simulated data: the noise floor and the pinch
baseline, scored with the same metric function on the same configurations as the model.

- **Noise floor**: the dataset's noise-free forces (``force_clean_<finger>_y|z`` of
  ``configs.parquet``) scored as a prediction against each configuration's repeated, noisy press
  labels. No predictor can be expected to do better on average: it is what the labels' own
  noise costs.
- **Pinch baseline** (`vistac_learn.evaluate.pinch`): the image-only physics prediction,
  scored on the unrotated images (it reads geometry, so rotating the image changes its input
  only by resampling). It costs tens of milliseconds per image, so its summary is cached in the
  dataset's ``cache/`` folder, keyed by the dataset's fingerprint, the labels, the settings, the
  rows and the fingers.

Both need the simulator's clean forces: `has_clean_forces` is False for an ingested (real)
dataset, and evaluations then skip them.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import time
from pathlib import Path

import numpy as np

from vistac.dataset import DatasetTables
from vistac.dataset.files import atomic_write_json
from vistac.dataset.schema import clean_force_columns
from vistac_learn.data.fingertip_table import locator_fingerprint
from vistac_learn.data.samples import RotationCfg
from vistac_learn.evaluate.pinch import PinchCfg, dataset_friction, pinch_predictions
from vistac_learn.metrics.scoring import score

CACHE_VERSION = 2  # bump when the pinch baseline's output changes; invalidates cached results
LABELS = {"noise_floor": "noise floor (clean force)", "pinch": "pinch baseline"}


def clean_yz_columns(finger: str) -> list[str]:
    """The (y, z) noise-free force columns of a finger in ``configs.parquet`` (the label's
    plane; `vistac.dataset.schema.clean_force_columns` owns the names)."""
    return clean_force_columns(finger)[1:]  # (x, y, z) -> (y, z)


def has_clean_forces(tables: DatasetTables, fingers: tuple[str, ...]) -> bool:
    """Whether the dataset holds finite noise-free forces of every finger (simulated data)."""
    cols = [c for f in fingers for c in clean_yz_columns(f)]
    if not all(c in tables.configs for c in cols):
        return False
    return bool(np.isfinite(tables.configs[cols].to_numpy(float)).all())


def noise_floor(tables: DatasetTables, rows: np.ndarray, fingers: tuple[str, ...]
                ) -> dict[str, dict]:
    """Cone metrics of the noise-free forces scored as predictions, per finger.

    Each force's (F_y, F_z) is reduced to its unit direction first, the target a model learns
    (angles and slopes do not depend on the scale; the MSE does).

    Args:
        tables: A simulated dataset (see `has_clean_forces`).
        rows: Configuration rows (one prediction each).
        fingers: Fingers to score.

    Returns:
        Finger -> scalar summary (`vistac_learn.metrics.summarize` keys).
    """
    rows = np.asarray(rows, dtype=np.int64)
    pred = []
    for f in fingers:
        yz = tables.configs[clean_yz_columns(f)].to_numpy(float)[rows]
        norm = np.hypot(yz[:, 0], yz[:, 1])[:, None]
        pred.append(np.where(norm > 0, yz / np.where(norm > 0, norm, 1.0), (0.0, -1.0)))
    return score(np.concatenate(pred, axis=1), tables, rows, rows, fingers)


def _cache_path(tables: DatasetTables, rows: np.ndarray, fingers: tuple[str, ...],
                cfg: PinchCfg, cache_dir: Path | None) -> Path:
    h = hashlib.sha256()
    h.update(json.dumps({"v": CACHE_VERSION, "cfg": dataclasses.asdict(cfg),
                         "fingers": list(fingers)}, sort_keys=True).encode())
    h.update(locator_fingerprint(cfg.locator).encode())  # it locates the fingers itself
    h.update(np.asarray(rows, dtype=np.int64).tobytes())
    h.update(tables.fingerprint().encode())  # manifest, configurations and images
    for f in fingers:  # and the labels it is scored against (not in the fingerprint)
        for r in rows:
            h.update(np.ascontiguousarray(tables.cones[f][r], dtype=np.float64).tobytes())
    folder = cache_dir if cache_dir is not None else tables.root / "cache"
    return Path(folder) / f"pinch-{h.hexdigest()[:20]}.json"


def pinch_reference(tables: DatasetTables, rows: np.ndarray, fingers: tuple[str, ...],
                    cfg: PinchCfg | None = None, cache_dir: str | Path | None = None,
                    progress: bool = False) -> dict:
    """The pinch baseline's summary on unrotated images, computed once and cached.

    Args:
        tables: The dataset.
        rows: Configuration rows.
        fingers: Fingers to score.
        cfg: Baseline settings (default `PinchCfg()`).
        cache_dir: Folder of the cached summary (default ``<dataset>/cache``); an unwritable
            folder only skips the caching.
        progress: Show a progress bar.

    Returns:
        {"metrics": finger -> scalar summary, "ms_per_image", "failures", "friction",
        "rotations": "none", "n_configs"}.
    """
    rows = np.asarray(rows, dtype=np.int64)
    cfg = cfg or PinchCfg()
    path = _cache_path(tables, rows, fingers, cfg, Path(cache_dir) if cache_dir else None)
    try:  # a damaged or foreign cache file is computed again, never trusted
        cached = json.loads(path.read_text())
        if isinstance(cached, dict) and isinstance(cached.get("metrics"), dict):
            return cached
    except (OSError, ValueError):
        pass
    t0 = time.perf_counter()
    pred, item_row, _, failures = pinch_predictions(tables, rows, fingers, RotationCfg("none", 1),
                                                    cfg, progress)
    elapsed = time.perf_counter() - t0
    res = {"metrics": score(pred, tables, rows, item_row, fingers),
           "ms_per_image": 1000.0 * elapsed / max(len(rows), 1), "failures": int(failures),
           "friction": cfg.friction if cfg.friction is not None else dataset_friction(tables),
           "rotations": "none", "n_configs": int(len(rows))}
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_json(path, res)
    except OSError:
        pass  # a read-only dataset: recomputed next time
    return res


def references(tables: DatasetTables, rows: np.ndarray, fingers: tuple[str, ...],
               cfg: PinchCfg | None = None, cache_dir: str | Path | None = None,
               progress: bool = False) -> dict | None:
    """Both references on the given rows, or None for a dataset without clean forces.

    Returns:
        {"noise_floor": {"metrics": ...}, "pinch": `pinch_reference` result}.
    """
    if not has_clean_forces(tables, fingers):
        return None
    return {"noise_floor": {"metrics": noise_floor(tables, rows, fingers)},
            "pinch": pinch_reference(tables, rows, fingers, cfg, cache_dir, progress)}


def reference_entries(refs: dict | None, fingers: tuple[str, ...]) -> list[tuple[str, dict]]:
    """(label, summary) rows of the references for `format_table`, floor first."""
    if not refs:
        return []
    return [(f"{LABELS[k]} ({f})", refs[k]["metrics"][f]) for k in LABELS if k in refs
            for f in fingers if f in refs[k]["metrics"]]
