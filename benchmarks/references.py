"""The references every model on simulated data is measured against, per finger, on one split.

Rows (all scored with `vistac_learn.metrics` on the same configurations, one prediction each,
unrotated images):

- noise floor: the dataset's noise-free forces as the prediction (what the labels' own noise
  costs; `vistac_learn.evaluate.references.noise_floor`);
- pinch baseline: the closing axis through the contact points in each finger's frame, clamped
  to the friction cone (`vistac_learn.evaluate.pinch`), with its cost per image (wall and CPU);
- geometric baseline: the surface normal at the contact (`vistac_learn.evaluate.geometric`);
- mean label: the training split's mean label for every configuration (a constant);
- pinch and geometric again on images made less synthetic: Gaussian camera noise
  (``--noise-std`` of the 0-255 range, per pixel and channel, seeded per configuration)
  followed by a JPEG round trip through OpenCV (``--jpeg-quality``).

Writes ``<name>.md`` and ``<name>.json`` into ``--out`` (default ``benchmarks/results``).

Usage (the issue's dataset):
    vistac generate --n 3000 --noise 0.05 --seed 21 --split-by object --out bench/refs/data
    python benchmarks/references.py --data bench/refs/data
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from learnbench import mean_entry, save, table

from vistac.dataset import FINGERS, open_tables
from vistac_learn.data.fingertips import read_rgb
from vistac_learn.evaluate import geometric, pinch
from vistac_learn.evaluate.references import noise_floor
from vistac_learn.metrics.scoring import score

EXTRA = (("ms / image (wall)", "ms_per_image"), ("CPU ms / image", "cpu_ms_per_image"),
         ("fingers not found", "failures"))


@dataclass(frozen=True)
class Photoish:
    """Camera noise then a JPEG round trip, seeded per configuration row."""

    noise_std: float  # of the 0-255 range
    jpeg_quality: int
    seed: int

    def __call__(self, img: np.ndarray, row: int) -> np.ndarray:
        rng = np.random.default_rng([self.seed, int(row)])
        noisy = np.clip(img + rng.normal(0.0, self.noise_std, img.shape), 0, 255).astype(np.uint8)
        ok, buf = cv2.imencode(".jpg", cv2.cvtColor(noisy, cv2.COLOR_RGB2BGR),
                               [cv2.IMWRITE_JPEG_QUALITY, self.jpeg_quality])
        assert ok
        return cv2.cvtColor(cv2.imdecode(buf, cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)


def _entry(label, tables, rows, predict_one, perturb=None) -> dict:
    """Score an image predictor on the unrotated (optionally perturbed) images; time it."""
    preds, failures = [], 0
    wall, cpu = 0.0, 0.0
    for row in rows:
        img = read_rgb(tables.image_path(row))
        if perturb is not None:
            img = perturb(img, row)
        w0, c0 = time.perf_counter(), time.process_time()
        p, lost = predict_one(img)
        wall, cpu = wall + time.perf_counter() - w0, cpu + time.process_time() - c0
        preds.append(p)
        failures += lost
    return {"label": label, "fingers": list(FINGERS),
            "metrics": score(np.array(preds), tables, rows, rows, FINGERS),
            "by_family": by_family(np.array(preds), tables, rows),
            "ms_per_image": 1000 * wall / len(rows), "cpu_ms_per_image": 1000 * cpu / len(rows),
            "failures": int(failures)}


def by_family(pred: np.ndarray, tables, rows: np.ndarray) -> dict:
    """Median angle to the cone mean per object family (and count), per finger."""
    fam = tables.configs["object_family"].to_numpy()[rows] \
        if "object_family" in tables.configs else np.full(len(rows), "all")
    out = {}
    for k in sorted(set(fam)):
        sel = fam == k
        res = score(pred[sel], tables, rows[sel], rows[sel], FINGERS)
        out[str(k)] = {"n": int(sel.sum()), **{f: res[f]["angle_to_mean_median_deg"]
                                                for f in FINGERS}}
    return out


def family_table(entries: list[dict]) -> str:
    """Markdown: median angle to the cone mean per object family, index / thumb."""
    fams = sorted({k for e in entries for k in e.get("by_family", {})})
    head = ["model / setting", *(f"{k} (n {entries[0]['by_family'][k]['n']})" for k in fams)]
    lines = ["| " + " | ".join(head) + " |", "|---" * len(head) + "|"]
    for e in entries:
        if "by_family" in e:
            cells = [f"{e['by_family'][k]['index']:.2f} / {e['by_family'][k]['thumb']:.2f}"
                     for k in fams]
            lines.append("| " + " | ".join([e["label"], *cells]) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path, required=True, help="a simulated dataset")
    ap.add_argument("--split", default="test")
    ap.add_argument("--limit", type=int, default=0, help="score only the first N rows (0: all)")
    ap.add_argument("--noise-std", type=float, default=4.0,
                    help="camera noise std, of the 0-255 range")
    ap.add_argument("--jpeg-quality", type=int, default=90)
    ap.add_argument("--seed", type=int, default=0, help="seed of the camera noise")
    ap.add_argument("--out", type=Path, default=Path(__file__).resolve().parent / "results")
    ap.add_argument("--name", default="references")
    args = ap.parse_args(argv)

    t = open_tables(args.data)
    rows = t.rows(args.split)  # sorted row indices
    if args.limit:
        rows = rows[:args.limit]
    colours = {f: t.finger_rgb(f) for f in FINGERS}
    mu = pinch.dataset_friction(t)
    pinch_one = lambda img: pinch.predict_image(img, colours, FINGERS, mu)  # noqa: E731
    geo_one = lambda img: geometric.predict_image(img, colours, FINGERS)  # noqa: E731
    photoish = Photoish(args.noise_std, args.jpeg_quality, args.seed)
    tag = f"noise {args.noise_std:g}/255 + JPEG {args.jpeg_quality}"

    clean = np.concatenate([t.configs[[f"force_clean_{f}_y", f"force_clean_{f}_z"]]
                            .to_numpy(float)[rows] for f in FINGERS], axis=1)
    entries = [{"label": "noise floor (clean force)", "fingers": list(FINGERS),
                "metrics": noise_floor(t, rows, FINGERS),
                "by_family": by_family(clean, t, rows)},
               _entry("pinch baseline", t, rows, pinch_one),
               _entry("geometric baseline", t, rows, geo_one)]
    mean = mean_entry(args.data)
    if args.split != "test" or args.limit:  # mean_entry scores the whole test split
        mean = {**mean, "metrics": score(
            np.tile(np.concatenate([t.mean_label(f)[t.rows("train")].mean(axis=0)
                                    for f in FINGERS]), (len(rows), 1)),
            t, rows, rows, FINGERS)}
    entries.append(mean)
    entries += [_entry(f"pinch baseline, {tag}", t, rows, pinch_one, photoish),
                _entry(f"geometric baseline, {tag}", t, rows, geo_one, photoish)]

    result = {"data": str(args.data.resolve()), "fingerprint": t.fingerprint(),
              "split": args.split, "n_configs": int(len(rows)), "friction": mu,
              "noise_std": args.noise_std, "jpeg_quality": args.jpeg_quality,
              "seed": args.seed, "entries": entries}
    gen = t.manifest.get("config") or {}
    made = (f"`vistac generate --n {gen.get('n')} --noise {(gen.get('effects') or {}).get('noise')}"
            f" --seed {gen.get('seed')} --split-by {(gen.get('split') or {}).get('by')}`")
    md = "\n".join([
        f"# References on {made}, split {args.split} ({len(rows)} configurations)",
        "",
        "`python benchmarks/references.py " + " ".join(argv if argv is not None
                                                       else sys.argv[1:]) + "`",
        "",
        "Median angle to the cone mean and the study's metrics, one prediction per "
        "configuration (unrotated image); friction coefficient of the pinch cone "
        f"{mu:g} (the dataset's). Times: the predictor alone (image decoding excluded), "
        "this process, on a machine shared with other jobs.",
        "",
        table(entries, EXTRA),
        "",
        "Median angle to the cone mean (deg, index / thumb) by object family:",
        "",
        family_table(entries),
    ])
    save(args.out, args.name, result, md, datasets=(args.data,))
    return 0


if __name__ == "__main__":
    sys.exit(main())
