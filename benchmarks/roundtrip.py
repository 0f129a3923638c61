"""Round trip: `vistac generate --recordings` under a preset, `vistac ingest` of its recordings,
ingested unit labels against `presses.parquet` on (`config_id`, `repeat`).

Reports per preset and finger the median and 95th-percentile angle between the generated and
the ingested label (target: median <= 1 degree under `lab`), how many grasps were rejected and
why, and how many generated presses the ingest found no grasp for (or found extra ones).

    .venv/bin/python benchmarks/roundtrip.py --n 200 --presets lab harsh --workers 2
"""

from __future__ import annotations

import argparse
import json
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from vistac.dataset.ingest.config import IngestCfg, IngestSources
from vistac.dataset.ingest.run import ingest
from vistac.provenance import provenance
from vistac_sim.generate.run import generate

FINGERS = ("index", "thumb")


def angles_deg(a: pd.DataFrame, b: pd.DataFrame, finger: str) -> np.ndarray:
    """Angle between the unit labels of two joined tables (suffixes _g and _i), degrees."""
    ya, za = a[f"r_y_{finger}_g"].to_numpy(), a[f"r_z_{finger}_g"].to_numpy()
    yb, zb = b[f"r_y_{finger}_i"].to_numpy(), b[f"r_z_{finger}_i"].to_numpy()
    return np.degrees(np.abs(np.arctan2(ya * zb - za * yb, ya * yb + za * zb)))


def compare(gen: Path, ing: Path) -> dict:
    """Figures of one round trip (generated dataset `gen`, ingested dataset `ing`)."""
    a = pd.read_parquet(gen / "presses.parquet")
    b = pd.read_parquet(ing / "presses.parquet")
    m = a.merge(b, on=["config_id", "repeat"], suffixes=("_g", "_i"))
    rejected = pd.read_csv(ing / "rejected.csv")
    manifest = json.loads((ing / "manifest.json").read_text())
    keys_a = set(zip(a["config_id"], a["repeat"], strict=True))
    keys_r = set(zip(rejected["config_id"], rejected["repeat"], strict=True))
    keys_b = set(zip(b["config_id"], b["repeat"], strict=True))
    out = {"presses": len(a), "joined": len(m), "rejected": len(rejected),
           "rejected_by_reason": manifest["rejected"]["by_reason"],
           "missed": len(keys_a - keys_b - keys_r), "extra": len((keys_b | keys_r) - keys_a),
           "dropped_configs": len(manifest["dropped_configs"])}
    for f in FINGERS:
        ang = angles_deg(m, m, f)
        out[f] = {"median_deg": float(np.median(ang)), "p95_deg": float(np.percentile(ang, 95)),
                  "max_deg": float(ang.max())}
        df = (m[f"force_{f}_z_g"] - m[f"force_{f}_z_i"]).abs()
        out[f]["median_abs_dFz_N"] = float(df.median())
    return out


def run(preset: str, n: int, seed: int, workers: int, root: Path, cfg: IngestCfg) -> dict:
    from vistac_sim.generate.config import GenerateCfg

    gcfg = GenerateCfg.from_preset(preset, recordings=True, n=n, seed=seed)
    gen, ing = root / f"gen_{preset}", root / f"ing_{preset}"
    t0 = time.perf_counter()
    generate(gcfg, gen, workers=workers, progress=False)
    t1 = time.perf_counter()
    ingest(IngestSources(images=gen / "images", recordings=gen / "recordings"), ing, cfg)
    t2 = time.perf_counter()
    return {"preset": preset, "n": n, "seed": seed, **compare(gen, ing),
            "generate_s": round(t1 - t0, 2), "ingest_s": round(t2 - t1, 2)}


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--n", type=int, default=200)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--presets", nargs="+", default=["lab"])
    p.add_argument("--workers", type=int, default=1)
    p.add_argument("--threshold", type=float, default=IngestCfg().threshold)
    p.add_argument("--keep", type=Path, default=None, help="keep the datasets in this folder")
    p.add_argument("--json", type=Path, default=None, help="write the results here")
    args = p.parse_args(argv)
    root = args.keep or Path(tempfile.mkdtemp(prefix="vistac_roundtrip_"))
    root.mkdir(parents=True, exist_ok=True)
    results = []
    try:
        for preset in args.presets:
            r = run(preset, args.n, args.seed, args.workers, root,
                    IngestCfg(threshold=args.threshold))
            results.append(r)
            print(f"{preset}: {r['presses']} presses, {r['joined']} joined, {r['rejected']} "
                  f"rejected {r['rejected_by_reason']}, missed {r['missed']}, extra "
                  f"{r['extra']}, dropped configs {r['dropped_configs']}  "
                  f"(generate {r['generate_s']} s, ingest {r['ingest_s']} s)")
            for f in FINGERS:
                q = r[f]
                print(f"  {f:5s} angle median {q['median_deg']:.3f} deg, p95 {q['p95_deg']:.3f}"
                      f" deg, max {q['max_deg']:.3f} deg; median |dF_z| "
                      f"{q['median_abs_dFz_N'] * 1000:.2f} mN")
    finally:
        if args.keep is None:
            shutil.rmtree(root, ignore_errors=True)
    if args.json:
        args.json.write_text(json.dumps({"results": results, "provenance": provenance()},
                                        indent=2) + "\n")


if __name__ == "__main__":
    main()
