"""A grid of clean vs `--preset photo` renders of the same configurations (and photo's masks).

Generates `--n` configurations twice with the same seed (clean, then photo with masks) and
tiles them: top row clean, middle row photo, bottom row photo's masks (table black, object
grey, index and thumb brighter).

    .venv/bin/python benchmarks/photo_grid.py --n 8 --seed 3
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import cv2
import numpy as np

from vistac.config import apply
from vistac_sim.generate.config import GenerateCfg
from vistac_sim.generate.run import generate

RESULTS = Path(__file__).parent / "results"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=8)
    ap.add_argument("--seed", type=int, default=3)
    ap.add_argument("--n-objects", type=int, default=8)
    ap.add_argument("--out", default=str(RESULTS / "photo_grid.png"))
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for preset in ("clean", "photo"):
            cfg = GenerateCfg.from_preset(preset, n=args.n, seed=args.seed)
            cfg = apply(cfg, {"objects": {"n_objects": args.n_objects},
                              "render": {"masks": preset == "photo"}})
            out = Path(tmp) / preset
            generate(cfg, out, workers=1, progress=False)
            names = sorted(p.name for p in (out / "images").iterdir())
            rows.append([cv2.imread(str(out / "images" / n)) for n in names])
            if preset == "photo":
                masks = [cv2.imread(str(out / "masks" / n), cv2.IMREAD_UNCHANGED) for n in names]
                rows.append([cv2.cvtColor((m * 80).astype(np.uint8), cv2.COLOR_GRAY2BGR)
                             for m in masks])
    pad = 4
    grid = np.full((3 * (227 + pad) - pad, args.n * (227 + pad) - pad, 3), 255, np.uint8)
    for r, row in enumerate(rows):
        for c, img in enumerate(row):
            y, x = r * (227 + pad), c * (227 + pad)
            grid[y:y + img.shape[0], x:x + img.shape[1]] = img
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(args.out, grid)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
