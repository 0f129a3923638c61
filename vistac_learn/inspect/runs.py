"""Where a model fails: the worst configurations of a run's evaluation, each image with the
true cone and mean label (black) and the model's prediction (blue) at every fingertip, beside
the evaluation's metrics table.

`vistac inspect RUN` reads what `vistac evaluate --run RUN` wrote (``<run>/eval/<split>*/``:
``metrics.json``, ``predictions.parquet``); it scores nothing itself. A configuration's error is
its prediction's angle to the mean label, averaged over its rotations and fingers.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd

from vistac.dataset import open_tables
from vistac.dataset.frames import sensor_to_image
from vistac.errors import UserError
from vistac_learn.data.variants import read_rgb
from vistac_learn.inspect import drawing
from vistac_learn.inspect.arrows import finger_arrows, has_simulator_tips


def find_evaluation(run: Path, split: str = "test") -> Path:
    """The newest evaluation folder of `run` on `split` (``eval/<split>``, ``eval/<split>-tta``
    or ``eval/<split>-no-tta``: `vistac_learn.evaluate.config.default_out_dir`).

    Raises:
        UserError: the run has none (how to make one in the message).
    """
    found = [p.parent for p in (run / "eval").glob(f"{split}*/metrics.json")
             if (p.parent / "predictions.parquet").is_file()]
    if not found:
        raise UserError(f"{run}: no evaluation on the {split} split (no eval/{split}*/metrics.json "
                        f"with predictions.parquet); run `vistac evaluate --run {run}` first")
    return max(found, key=lambda p: (p / "metrics.json").stat().st_mtime)


def worst_configurations(pred: pd.DataFrame, fingers: list[str], n: int) -> pd.DataFrame:
    """Per configuration: the angle to the mean label (deg) per finger and their mean, averaged
    over rotations, and the mean predicted (r_y, r_z) per finger; the `n` worst, worst first."""
    cols = {f"{f}_angle_to_mean_deg": "mean" for f in fingers}
    cols |= {f"pred_{f}_{a}": "mean" for f in fingers for a in "yz"}
    missing = [c for c in cols if c not in pred]
    if missing:
        raise UserError(f"predictions.parquet: missing column(s) {', '.join(missing)}")
    per = pred.groupby("config_id").agg(cols)
    per["error_deg"] = per[[f"{f}_angle_to_mean_deg" for f in fingers]].mean(axis=1)
    return per.sort_values("error_deg", ascending=False, kind="stable").head(n)


def inspect_run(run: str | Path, out: Path, *, worst: int, columns: int, size: int,
                split: str = "test") -> dict:
    """Write the worst configurations' sheet (``worst.png``) into `out`; returns what the
    report needs (evaluation folder, metrics table, the worst rows)."""
    run = Path(run)
    if not (run / "config.json").is_file():
        raise UserError(f"{run}: not a run folder (no config.json)")
    ev = find_evaluation(run, split)
    try:
        metrics = json.loads((ev / "metrics.json").read_text())
        pred = pd.read_parquet(ev / "predictions.parquet")
    except Exception as exc:  # a damaged JSON or Parquet file
        raise UserError(f"{ev}: unreadable evaluation ({' '.join(str(exc).split())[:120]}); "
                        f"run `vistac evaluate --run {run}` again") from None
    fingers = list(metrics.get("fingers") or ["index"])
    tables = open_tables(metrics.get("data") or "")
    rows_of = {int(c): r for r, c in enumerate(tables.configs["config_id"])}
    top = worst_configurations(pred, fingers, worst)
    simulated = has_simulator_tips(tables)
    tiles = []
    for cid, rec in top.iterrows():
        row = rows_of.get(int(cid))
        if row is None:
            continue
        rgb = read_rgb(tables.image_path(row))
        img = rgb.copy()
        for f, a in finger_arrows(tables, row, rgb, simulated).items():
            if a is None or f not in fingers:
                continue
            p = np.array([rec[f"pred_{f}_y"], rec[f"pred_{f}_z"]])
            p = p / max(float(np.hypot(*p)), 1e-12)
            drawing.draw_finger(img, a.tip, a.mean, a.presses, sensor_to_image(p, a.axis, f))
        errs = " / ".join(f"{rec[f'{f}_angle_to_mean_deg']:.1f}" for f in fingers)
        tiles.append(drawing.caption(drawing.resized(img, size), f"{cid}: {errs} deg"))
    if tiles:
        drawing.write_png(out / "worst.png", drawing.grid(tiles, columns))
    return {"evaluation": ev, "metrics": metrics, "fingers": fingers, "worst": top,
            "data": tables.root}
