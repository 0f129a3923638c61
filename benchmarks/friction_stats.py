"""Friction is physics: the analytic check's errors and the label statistics of drawn grasps.

1. Analytic: a flat face pressed at known push-to-normal angles (a vertical wall pushed at a yaw
   angle, faces tilted up and down pushed horizontally) for several friction coefficients; the
   settled force must make min(push angle, atan mu) with the normal
   (`vistac_sim.physics.analytic`).
2. Drawn grasps: `vistac generate` on the default procedural objects at each `--friction`; per
   contact, the push-to-normal angle (the hand closes along its own axis), the force-to-normal
   angle (median, p95, max), the share of contacts on the cone's edge (within 0.5 deg of
   atan mu: slipping), the bound atan(mu) + 2 deg, and the median |r_y| of the labels (how far
   the force leans across the pad).

Writes `friction_analytic.csv`, `friction_stats.csv` and `friction_stats.md` into `--results`.

    .venv/bin/python benchmarks/friction_stats.py --n 400 --workers 1
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from vistac.config import apply
from vistac.dataset import FINGERS
from vistac_sim.generate.config import GenerateCfg
from vistac_sim.generate.run import generate
from vistac_sim.physics.analytic import FACES, analytic_press

RESULTS = Path(__file__).parent / "results"
ANALYTIC_FRICTIONS = (0.0, 0.3, 0.5, 0.8, 1.0)
ANALYTIC_PUSH_DEG = (0.0, 5.0, 10.0, 20.0, 30.0, 40.0, 45.0)
EDGE_DEG = 0.5  # a contact this close to atan(mu) counts as on the cone's edge


def analytic_table() -> pd.DataFrame:
    """Every face x friction x push angle of the analytic check."""
    rows = []
    for face in FACES:
        for mu in ANALYTIC_FRICTIONS:
            for push in ANALYTIC_PUSH_DEG:
                r = analytic_press(face, push, mu)
                rows.append({"face": face, "friction": mu, "push_deg": push,
                             "expected_deg": r.expected_deg, "measured_deg": r.measured_deg,
                             "error_deg": r.error_deg})
    return pd.DataFrame(rows)


def contact_angles(configs: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
    """Per contact (both fingers): push-to-normal and force-to-normal angles, degrees.

    The push (world xy, the hand's closing axis) is turned into the finger's sensor frame (z =
    the finger axis, y = up x z, mirrored for the thumb; docs/dataset-format.md); the normal columns
    hold the outward normal there, so the push-to-normal angle is the angle between the push and
    minus the normal.
    """
    push, force = [], []
    for f, mirror in zip(FINGERS, (1.0, -1.0), strict=True):
        n = configs[[f"normal_{f}_{c}" for c in "xyz"]].to_numpy()
        n = n / np.linalg.norm(n, axis=1, keepdims=True)
        F = configs[[f"force_clean_{f}_{c}" for c in "xyz"]].to_numpy()
        a = configs[[f"approach_{f}_x", f"approach_{f}_y"]].to_numpy()
        p = configs[[f"push_{f}_x", f"push_{f}_y"]].to_numpy()
        p_s = np.c_[np.zeros(len(p)), mirror * (p[:, 1] * a[:, 0] - p[:, 0] * a[:, 1]),
                    (p * a).sum(1)]
        push.append(np.degrees(np.arccos(np.clip(-(p_s * n).sum(1), -1, 1))))
        cos = (F * n).sum(1) / np.linalg.norm(F, axis=1)
        force.append(np.degrees(np.arccos(np.clip(cos, -1, 1))))  # F and n both point at the pad
    return np.concatenate(push), np.concatenate(force)


def drawn_stats(frictions, n: int, workers: int, seed: int) -> pd.DataFrame:
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for mu in frictions:
            cfg = apply(GenerateCfg(n=n, seed=seed, repeats=1), {"physics": {"friction": mu}})
            t0 = time.perf_counter()
            manifest = generate(cfg, Path(tmp) / f"mu{mu}", workers=workers, progress=False)
            configs = pd.read_parquet(Path(tmp) / f"mu{mu}" / "configs.parquet")
            push, ang = contact_angles(configs)
            cone = float(np.degrees(np.arctan(mu)))
            rows.append({
                "friction": mu, "configs": len(configs), "contacts": len(ang),
                "push_median_deg": float(np.median(push)),
                "push_p95_deg": float(np.percentile(push, 95)), "push_max_deg": float(push.max()),
                "force_median_deg": float(np.median(ang)),
                "force_p95_deg": float(np.percentile(ang, 95)), "force_max_deg": float(ang.max()),
                "atan_mu_deg": cone,
                "share_on_cone_edge": float(np.mean(np.abs(ang - cone) <= EDGE_DEG)) if mu else 0.0,
                "share_beyond_atan_mu_plus_2": float(np.mean(ang > cone + 2.0)),
                "median_abs_r_y": float(np.median(np.abs(np.concatenate(
                    [configs[f"force_clean_{f}_y"] / np.hypot(configs[f"force_clean_{f}_y"],
                                                              configs[f"force_clean_{f}_z"])
                     for f in FINGERS])))),
                "redraws": manifest.get("redraws", {}).get("total", 0),
                "wall_s": time.perf_counter() - t0,
            })
            print(rows[-1], flush=True)
    return pd.DataFrame(rows)


def markdown(analytic: pd.DataFrame, stats: pd.DataFrame, args) -> str:
    worst = analytic.assign(abs_err=analytic.error_deg.abs()).groupby(["face", "friction"])[
        "abs_err"].max().unstack("face")
    lines = ["# Friction statistics", "",
             f"`benchmarks/friction_stats.py --n {args.n} --seed {args.seed}` "
             f"(default config, procedural objects, 1 press per configuration).", "",
             "## Analytic check: max |measured - min(push, atan mu)| over push angles "
             f"{', '.join(f'{p:g}' for p in ANALYTIC_PUSH_DEG)} deg", "",
             "| friction | " + " | ".join(worst.columns) + " |",
             "|---|" + "---|" * len(worst.columns)]
    for mu, row in worst.iterrows():
        lines.append(f"| {mu:g} | " + " | ".join(f"{v:.3f}" for v in row) + " |")
    lines += ["", f"Largest error overall: {analytic.error_deg.abs().max():.3f} deg "
              f"({len(analytic)} presses).", "",
              "## Drawn grasps: angles per contact (degrees)", "",
              "| friction | contacts | push-to-normal median / p95 / max | force-to-normal "
              "median / p95 / max | atan mu | on cone edge | beyond atan mu + 2 | median abs r_y |",
              "|---|---|---|---|---|---|---|---|"]
    for _, r in stats.iterrows():
        lines.append(
            f"| {r.friction:g} | {int(r.contacts)} | {r.push_median_deg:.2f} / "
            f"{r.push_p95_deg:.2f} / {r.push_max_deg:.2f} | {r.force_median_deg:.2f} / "
            f"{r.force_p95_deg:.2f} / "
            f"{r.force_max_deg:.2f} | {r.atan_mu_deg:.2f} | {100 * r.share_on_cone_edge:.1f} % "
            f"| {100 * r.share_beyond_atan_mu_plus_2:.1f} % | {r.median_abs_r_y:.3f} |")
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=400, help="configurations per friction")
    ap.add_argument("--frictions", type=float, nargs="+", default=[0.0, 0.3, 0.8])
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--results", type=Path, default=RESULTS)
    args = ap.parse_args()
    analytic = analytic_table()
    print(analytic.to_string(index=False), flush=True)
    stats = drawn_stats(args.frictions, args.n, args.workers, args.seed)
    args.results.mkdir(parents=True, exist_ok=True)
    analytic.to_csv(args.results / "friction_analytic.csv", index=False)
    stats.to_csv(args.results / "friction_stats.csv", index=False)
    md = markdown(analytic, stats, args)
    (args.results / "friction_stats.md").write_text(md)
    print(md)


if __name__ == "__main__":
    main()
