"""The text summary of a dataset: what it holds and how it was made, as lines (the CLI prints
them, `report.md` lists them)."""

from __future__ import annotations

from collections import Counter

import numpy as np
import pandas as pd

from vistac.dataset import FINGERS, SPLITS
from vistac.dataset.schema import box_columns, redraw_counts
from vistac_learn.inspect.readable import Readable

TOP_OBJECTS = 8
"""Objects listed by name (the most frequent); the rest are counted."""


def _counts(series: pd.Series) -> str:
    c = Counter(series.astype(str))
    return ", ".join(f"{k} {v}" for k, v in sorted(c.items()))


def redraw_reasons(readable: Readable) -> dict[str, int]:
    """Rejected grasp draws by reason: the manifest's, else summed over the configs column."""
    man = (readable.tables.manifest.get("redraws") or {}).get("by_reason")
    if man:
        return {str(k): int(v) for k, v in man.items()}
    c = readable.tables.configs
    total: Counter = Counter()
    if "redraw_reasons" in c:
        for cell in c["redraw_reasons"]:
            if not isinstance(cell, str):  # format 1 held text; not parsed here
                total.update(redraw_counts(cell))
    return dict(sorted(total.items()))


def rejected_grasps(readable: Readable) -> dict[str, int]:
    """Rejected recorded grasps by reason (ingested datasets)."""
    by = (readable.tables.manifest.get("rejected") or {}).get("by_reason") or {}
    return {str(k): int(v) for k, v in by.items()}


def unseen_fingers(configs: pd.DataFrame) -> dict[str, int]:
    """Per finger, configurations whose drawn finger box is empty or absent (simulated data:
    the finger is not in the image); {} when the dataset has no boxes (ingested)."""
    out = {}
    for f in FINGERS:
        cols = box_columns(f)
        if not set(cols) <= set(configs.columns):
            return {}
        b = configs[cols].to_numpy(float)
        if not np.isfinite(b).any():
            return {}
        out[f] = int((~np.isfinite(b).all(axis=1) | (b[:, 2] <= 0) | (b[:, 3] <= 0)).sum())
    return out


def _effects(manifest: dict) -> str:
    cfg = manifest.get("config") or {}
    effects = cfg.get("effects") or {}
    on = [f"{k} {v}" if isinstance(v, int | float) and not isinstance(v, bool) else k
          for k, v in effects.items() if v]
    return ", ".join(on) if on else "none"


def summary_lines(readable: Readable, sheet_not_found: dict[str, int] | None = None
                  ) -> list[str]:
    """The summary: counts per split, family and object, presses, how it was made, rejected
    draws or grasps by reason, fingers missing from the images, and the notes of what could
    not be read."""
    t = readable.tables
    c, p, man = t.configs, t.presses, t.manifest
    lines = [f"dataset {t.root}: {man.get('generator', 'unknown generator')}, format "
             f"{man.get('format_version', '?')}"]
    lines.append(f"configurations: {len(c)}" + (
        " (" + ", ".join(f"{s} {int((c['split'] == s).sum())}" for s in SPLITS) + ")"
        if "split" in c else ""))
    if "object_family" in c:
        lines.append(f"families: {_counts(c['object_family'])}")
    if "object_id" in c:
        top = c["object_id"].astype(str).value_counts()
        shown = ", ".join(f"{k} {v}" for k, v in top.head(TOP_OBJECTS).items())
        rest = f" and {len(top) - TOP_OBJECTS} more" if len(top) > TOP_OBJECTS else ""
        lines.append(f"objects: {len(top)} ({shown}{rest})")
    if "config_id" in p and len(c):
        per = p.groupby("config_id").size()
        each = f"{per.min()}" if per.min() == per.max() else f"{per.min()}-{per.max()}"
        lines.append(f"presses: {len(p)} ({each} per configuration)")
    else:
        lines.append(f"presses: {len(p)}")
    cfg = man.get("config") or {}
    if man.get("generator") == "vistac generate":
        lines.append(f"made with: seed {man.get('seed')}, {cfg.get('repeats', '?')} repeats, "
                     f"effects: {_effects(man)}")
    redraws = redraw_reasons(readable)
    if redraws:
        lines.append(f"rejected grasp draws: {sum(redraws.values())} ("
                     + ", ".join(f"{k} {v}" for k, v in redraws.items()) + ")")
    rejected = rejected_grasps(readable)
    if man.get("generator") == "vistac ingest":
        lines.append(f"rejected recorded grasps: {sum(rejected.values())} ("
                     + (", ".join(f"{k} {v}" for k, v in rejected.items()) or "none") + ")")
        dropped = man.get("dropped_configs") or []
        if dropped:
            lines.append(f"recordings without a usable grasp (left out): {len(dropped)}")
    unseen = unseen_fingers(c)
    if unseen:
        lines.append("fingers not in the image (empty box): "
                     + ", ".join(f"{f} {n}" for f, n in unseen.items()))
    if sheet_not_found and any(sheet_not_found.values()):
        lines.append("fingertips not found on the contact sheet: "
                     + ", ".join(f"{f} {n}" for f, n in sheet_not_found.items()))
    lines += [f"note: {n}" for n in readable.notes]
    return lines
