"""Label spread vs `--noise`: the median per-configuration slope range (max - min of r_y / r_z
over a configuration's repeats, the study's cone width w) under the `clean` and `lab` presets.

    .venv/bin/python benchmarks/label_spread.py --n 100 --workers 2
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import pandas as pd

from vistac.provenance import provenance
from vistac_sim.generate.config import GenerateCfg
from vistac_sim.generate.run import generate

NOISES = (0.0, 0.01, 0.02, 0.05, 0.1, 0.2)


def cone_widths(presses: pd.DataFrame, finger: str) -> pd.Series:
    """Per configuration: max - min over its repeats of the slope r_y / r_z."""
    slope = presses[f"r_y_{finger}"] / presses[f"r_z_{finger}"]
    g = slope.groupby(presses["config_id"])
    return g.max() - g.min()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=100)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--presets", nargs="+", default=["clean", "lab"])
    ap.add_argument("--json", default=None, help="write the results here too")
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for preset in args.presets:
            for noise in NOISES:
                cfg = GenerateCfg.from_preset(preset, noise=noise, n=args.n, seed=args.seed)
                out = Path(tmp) / f"{preset}_{noise}"
                manifest = generate(cfg, out, workers=args.workers, progress=False)
                presses = pd.read_parquet(out / "presses.parquet")
                rows.append({"preset": preset, "noise": noise,
                             **{f"median_w_{f}": float(cone_widths(presses, f).median())
                                for f in ("index", "thumb")},
                             "wall_s": manifest["wall_time_s"]})
                print(rows[-1], flush=True)
    print(f"\nn = {args.n} configurations x 6 repeats, seed {args.seed}\n")
    print("| preset | noise | median cone width, index | median cone width, thumb | wall s |")
    print("|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['preset']} | {r['noise']} | {r['median_w_index']:.4f} | "
              f"{r['median_w_thumb']:.4f} | {r['wall_s']:.1f} |")
    if args.json:
        Path(args.json).write_text(json.dumps({"rows": rows, "provenance": provenance()}, indent=2))


if __name__ == "__main__":
    main()
