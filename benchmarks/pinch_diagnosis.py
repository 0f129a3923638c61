"""Which part of a trained pinch model's geometry limits it: swap in the simulator's, one at a time.

Loads a run of the ``pinch`` view (its best weights), predicts the contact points p, normals n
and crop tilts phi of a split (the validation split by default: this is a tool for choosing
what to improve, so it never reads the test split unless asked), and scores the label composed
from the model's geometry with one part replaced by the simulator's truth. A part whose
replacement helps much is the one to improve. Also prints the median error of each part.

Usage:
    python benchmarks/pinch_diagnosis.py --run R [--split val]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
import torch

from vistac.dataset import FINGERS, open_tables
from vistac_learn.data.fingertip_table import FingertipTable, fingertip_table
from vistac_learn.data.loading import loader
from vistac_learn.evaluate.run import RETRAIN
from vistac_learn.metrics.scoring import score
from vistac_learn.models.pinch import compose_labels
from vistac_learn.train.build import build_model, build_samples, input_size
from vistac_learn.train.checkpoints import load_checkpoint, load_weights
from vistac_learn.train.config import TrainCfg


def diagnose(run: Path, split: str = "val", tips: FingertipTable | None = None) -> dict:
    """Median angle to the cone mean per variant and finger, and the parts' median errors;
    the crops around `tips` (default: the located fingertips)."""
    cfg = TrainCfg(**json.loads((run / "config.json").read_text())["train"])
    t = open_tables(cfg.data)
    model = build_model(cfg)
    path = run / "checkpoints" / "best.pt"
    load_weights(model, load_checkpoint(path, ("model",), RETRAIN)["model"], path, RETRAIN)
    model.eval()
    if tips is None:
        tips = fingertip_table(t, cache_dir=cfg.cache_dir)
    ds = build_samples(cfg, t, split, input_size(cfg, model), tips)
    preds: dict[str, list[np.ndarray]] = {}
    errs = []
    with torch.no_grad():
        for b in loader(ds, 128):
            _, g = model(b["image"], b["side"], aux=True)
            a, side = b["aux"], b["side"]
            truth = {"p": a[..., 0:2], "normal": a[..., 2:4], "phi": a[..., 4]}
            variants = {"model": {}, "simulator p": {"p"}, "simulator normal": {"normal"},
                        "simulator phi": {"phi"}, "simulator p, normal, phi":
                        {"p", "normal", "phi"}}
            for name, swap in variants.items():
                parts = {k: truth[k] if k in swap else g[k] for k in truth}
                lab = compose_labels(parts["p"], parts["normal"], parts["phi"],
                                     torch.zeros_like(parts["phi"]), side, model.mu)
                preds.setdefault(name, []).append(lab.reshape(len(a), -1).numpy())
            cos = (g["normal"] * truth["normal"]).sum(-1).clamp(-1, 1)
            errs.append(np.concatenate([
                (g["p"] - truth["p"]).norm(dim=-1).numpy(),
                np.degrees((g["phi"] - truth["phi"]).abs().numpy()),
                np.degrees(torch.arccos(cos).numpy())], axis=1))
    rows = t.rows(split)
    out = {"run": str(run), "split": split, "angle_to_mean_median_deg": {}}
    for name, chunks in preds.items():
        m = score(np.concatenate(chunks).astype(float), t, rows, rows, FINGERS)
        out["angle_to_mean_median_deg"][name] = {f: float(m[f]["angle_to_mean_median_deg"])
                                                 for f in FINGERS}
    e = np.nanmedian(np.concatenate(errs), axis=0)
    out["median_error"] = {f: {"p_half_sides": float(e[i]), "phi_deg": float(e[2 + i]),
                               "normal_deg": float(e[4 + i])} for i, f in enumerate(FINGERS)}
    return out


def main(argv: list[str] | None = None) -> int:
    """Command-line entry."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--run", required=True, type=Path)
    p.add_argument("--split", default="val", choices=("train", "val", "test"))
    args = p.parse_args(argv)
    res = diagnose(args.run, args.split)
    print("| label composed from | index (deg) | thumb (deg) |\n|---|---|---|")
    for name, v in res["angle_to_mean_median_deg"].items():
        print(f"| {name} | {v['index']:.2f} | {v['thumb']:.2f} |")
    print(json.dumps(res["median_error"], indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
