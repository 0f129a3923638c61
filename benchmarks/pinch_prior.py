"""What contact geometry allows: the pinch model's composition fed with known geometry, no learning.

Scores, on the test split (median angle to the cone mean, both fingers), the label that
`vistac_learn.models.pinch.compose_labels` composes through the ``pinch`` view from:

- the simulator's contact points, normals and finger directions (`data.contacts`): how close
  the physics "closing axis, clamped to the friction cone" comes to the labels;
- the same, but the finger direction taken from the located finger (no tilt correction):
  why the model predicts the crop's tilt ``phi``;
- the same, without the friction clamp: what the cone adds;
- the bare prior: the line between the two crop centres (the fronts of the located
  fingertips), no normal, no clamp: what an untrained model starts from;
- the line between the located tip centres (the fingertips' circle centres), no clamp;

beside the noise floor (the noise-free force scored like a prediction). A trained model sits
between the bare prior and the first row.

Usage:
    python benchmarks/pinch_prior.py --data D [--out benchmarks/results]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
import torch

from vistac.dataset import FINGERS, open_tables, unit_labels
from vistac.dataset.schema import clean_force_columns
from vistac.provenance import provenance
from vistac_learn.data.fingertip_table import FingertipTable, fingertip_table
from vistac_learn.data.loading import loader
from vistac_learn.data.samples import SampleSet, SampleSpec
from vistac_learn.data.views import TipCfg, make_view
from vistac_learn.metrics.scoring import score
from vistac_learn.models.pinch import MU, compose_labels

NO_CLAMP = 1e6  # a friction coefficient whose cone holds every direction


def composed(data: Path, split: str = "test", tips: FingertipTable | None = None
             ) -> dict[str, np.ndarray]:
    """(N, 4) predictions of each geometry variant for the split's configurations, in crops
    around `tips` (default: the dataset's located fingertips)."""
    t = open_tables(data)
    rows = t.rows(split)
    ds = SampleSet(t, rows, SampleSpec(make_view("pinch"), 48, FINGERS),
                   tips=tips if tips is not None else fingertip_table(t))
    out: dict[str, list[np.ndarray]] = {}
    for b in loader(ds, 256):
        aux, side = b["aux"].double(), b["side"].double()
        known = torch.isfinite(aux).all(-1, keepdim=True)
        aux = torch.where(known, aux, torch.tensor([0.0, 0.0, 0.0, -1.0, 0.0]).double())
        p, n, phi = aux[..., 0:2], aux[..., 2:4], aux[..., 4]
        zero, down, tip = torch.zeros_like(phi), torch.zeros_like(n), torch.zeros_like(p)
        down[..., 1] = -1.0
        tip[..., 1] = -2.0 * TipCfg().forward / TipCfg().span  # crop units: half sides
        variants = {
            "simulator contacts, normals, finger axes": (p, n, phi, MU),
            "... finger axes as located (phi = 0)": (p, n, zero, MU),
            "... no friction clamp": (p, n, phi, NO_CLAMP),
            "bare prior: crop centre to crop centre": (torch.zeros_like(p), down, zero,
                                                       NO_CLAMP),
            "located tip centre to tip centre": (tip, down, zero, NO_CLAMP),
        }
        for name, (pp, nn_, ph, mu) in variants.items():
            lab = compose_labels(pp, nn_, ph, zero, side, mu).reshape(len(p), -1)
            out.setdefault(name, []).append(lab.numpy())
    return {k: np.concatenate(v) for k, v in out.items()}


def main(argv: list[str] | None = None) -> int:
    """Command-line entry."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--data", required=True, type=Path)
    p.add_argument("--out", type=Path, default=Path(__file__).parent / "results")
    args = p.parse_args(argv)
    t = open_tables(args.data)
    rows = t.rows("test")
    floor = np.concatenate([unit_labels(t.configs[clean_force_columns(f)].to_numpy(float))
                            for f in FINGERS], axis=1)[rows]
    entries = {"noise floor (noise-free force)": floor, **composed(args.data)}
    lines = ["| geometry composed into the label | index (deg) | thumb (deg) |", "|---|---|---|"]
    result = {}
    for name, pred in entries.items():
        m = score(pred, t, rows, rows, FINGERS)
        result[name] = {f: float(m[f]["angle_to_mean_median_deg"]) for f in FINGERS}
        lines.append(f"| {name} | {result[name]['index']:.2f} | {result[name]['thumb']:.2f} |")
    md = "\n".join(lines)
    print(md)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "pinch_prior.md").write_text(
        f"Median angle to the cone mean on the test split of {args.data} "
        f"({len(rows)} configurations), `python benchmarks/pinch_prior.py`.\n\n{md}\n")
    (args.out / "pinch_prior.json").write_text(json.dumps(
        {"dataset": str(args.data), "split": "test", "n": int(len(rows)),
         "provenance": provenance([args.data]),
         "median_angle_to_mean_deg": result}, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
