"""The contact sheet: sampled configurations of every split and object family, each image with
its fingers' force directions drawn at the fingertips (mean label and the cone of the presses),
so that a label in the wrong frame shows at a glance; with masks, their outlines."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pandas as pd

from vistac.dataset import FINGERS
from vistac.dataset.reader import DatasetTables
from vistac.errors import UserError
from vistac_learn.data.variants import read_rgb
from vistac_learn.inspect import drawing
from vistac_learn.inspect.arrows import finger_arrows, has_simulator_tips


def sample_rows(configs: pd.DataFrame, per_group: int, max_tiles: int, seed: int) -> np.ndarray:
    """Up to `per_group` rows of each (split, family) group, in split then family order, at
    most `max_tiles` in all (fewer per group when there are many groups); deterministic."""
    if len(configs) == 0:
        return np.zeros(0, int)
    keys = [configs[c].astype(str) if c in configs else pd.Series("-", index=configs.index)
            for c in ("split", "object_family")]
    order = {"train": 0, "val": 1, "test": 2}
    groups = sorted(pd.DataFrame({"s": keys[0], "f": keys[1]}).groupby(["s", "f"]).groups.items(),
                    key=lambda kv: (order.get(kv[0][0], 3), kv[0][0], kv[0][1]))
    per_group = max(1, min(per_group, max_tiles // max(1, len(groups))))
    rng = np.random.default_rng(seed)
    rows: list[int] = []
    for _, idx in groups:
        idx = np.asarray(idx)
        rows += sorted(rng.choice(idx, size=min(per_group, len(idx)), replace=False).tolist())
    return np.array(rows[:max_tiles], int)


def tile(tables: DatasetTables, row: int, simulated: bool, size: int,
         missing: set[int]) -> tuple[np.ndarray, dict]:
    """One configuration's tile and what was found ({finger: arrows or None})."""
    c = tables.configs.iloc[row]
    label = f"{c.get('config_id', row)} {c.get('split', '')} {c.get('object_family', '')}"
    rgb = None
    if row not in missing:
        try:
            rgb = read_rgb(tables.image_path(row))
        except UserError:
            pass  # a damaged file: said on the tile and counted by `contact_sheet`
    if rgb is None:
        img = np.full((size, size, 3), 255, np.uint8)
        why = "image missing" if row in missing else "image unreadable"
        cv2.putText(img, why, (6, size // 2), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (200, 0, 0), 1,
                    cv2.LINE_AA)
        return drawing.caption(img, label), {"unreadable": row not in missing}
    found = finger_arrows(tables, row, rgb, simulated)
    img = rgb.copy()
    mask_path = tables.mask_path(row)
    if mask_path.is_file():
        mask = cv2.imread(str(mask_path), cv2.IMREAD_UNCHANGED)
        if mask is not None:
            drawing.outline_mask(img, mask)
    for f in FINGERS:
        a = found.get(f)
        if a is not None:
            drawing.draw_finger(img, a.tip, a.mean, a.presses)
    return drawing.caption(drawing.resized(img, size), label), found


def contact_sheet(tables: DatasetTables, out: Path, *, per_group: int, max_tiles: int,
                  columns: int, size: int, seed: int, missing: set[int]) -> dict:
    """Write the contact sheet PNG `out`; returns what it shows (rows, fingers not found,
    unreadable image files among the sampled ones)."""
    rows = sample_rows(tables.configs, per_group, max_tiles, seed)
    simulated = has_simulator_tips(tables)
    tiles, not_found = [], {f: 0 for f in FINGERS}
    unreadable = []
    for r in rows:
        t, found = tile(tables, int(r), simulated, size, missing)
        tiles.append(t)
        if found.get("unreadable"):
            unreadable.append(tables.image_path(int(r)).name)
        elif int(r) not in missing:
            for f in FINGERS:
                not_found[f] += int(found.get(f) is None)
    if tiles:
        drawing.write_png(out, drawing.grid(tiles, columns))
    return {"rows": rows.tolist(), "tips": "simulator" if simulated else "located",
            "not_found": not_found, "unreadable": unreadable}
