"""Angle between the frictionless contact force and the full-resolution mesh normal, per family.

With friction 0 a contact can only push along its normal, so the angle measures how well the
collision geometry (convex pieces) and the force reading agree with the visual mesh.

Usage:
    python benchmarks/frictionless_normals.py --n 2000 --out runs/bench_normals
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np

from vistac.dataset import open_tables
from vistac.provenance import provenance
from vistac_sim.objects.outlines import CONCAVE_FAMILIES


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--n", type=int, default=2000)
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", type=Path, default=Path("runs/bench_normals"))
    args = p.parse_args()
    data = args.out / "data"
    shutil.rmtree(args.out, ignore_errors=True)
    subprocess.run([sys.executable, "-m", "vistac.cli", "generate", "--n", str(args.n),
                    "--friction", "0", "--repeats", "1", "--seed", str(args.seed), "--workers",
                    str(args.workers), "--out", str(data), "--no-progress"], check=True)
    configs = open_tables(data).configs
    rows = {}
    for fam, group in configs.groupby("object_family"):
        ang = []
        for f in ("index", "thumb"):
            force = group[[f"force_clean_{f}_{c}" for c in "xyz"]].to_numpy()
            normal = group[[f"normal_{f}_{c}" for c in "xyz"]].to_numpy()
            cos = (force * normal).sum(1) / np.linalg.norm(force, axis=1)
            ang.append(np.degrees(np.arccos(np.clip(cos, -1, 1))))
        ang = np.concatenate(ang)
        rows[fam] = {"contacts": int(len(ang)), "median_deg": float(np.median(ang)),
                     "p95_deg": float(np.percentile(ang, 95)), "max_deg": float(ang.max()),
                     "concave": fam in CONCAVE_FAMILIES}
    summary = {}
    for kind, concave in (("primitive", False), ("concave", True)):
        sel = [r for r in rows.values() if r["concave"] == concave]
        summary[kind] = {"families": len(sel),
                         "worst_family_median_deg": max(r["median_deg"] for r in sel),
                         "worst_family_p95_deg": max(r["p95_deg"] for r in sel)}
    result = {"n": args.n, "families": rows, "summary": summary, "provenance": provenance()}
    (args.out / "result.json").write_text(json.dumps(result, indent=2) + "\n")
    print(f"{'family':<14}{'contacts':>9}{'median':>10}{'p95':>10}{'max':>10}  (degrees)")
    for fam, r in rows.items():
        print(f"{fam:<14}{r['contacts']:>9}{r['median_deg']:>10.4f}{r['p95_deg']:>10.4f}"
              f"{r['max_deg']:>10.3f}")
    print(json.dumps(summary, indent=2))
    shutil.rmtree(data)


if __name__ == "__main__":
    main()
