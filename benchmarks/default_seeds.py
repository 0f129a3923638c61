"""The default recipe over seeds: held-out accuracy with and without its test-time augmentation.

For each seed, the default recipe (`vistac train --data D --out R --finger both --seed S`, no
other option) is trained, or an existing run is given with ``--run SEED=FOLDER``, and scored
on the test split twice: as `vistac evaluate --run R` does by default (the recipe's mirrored
view averaged in) and with ``--tta off``. The noise floor and the pinch baseline of the same
configurations stand beside them (`vistac_learn.evaluate.references`). Training wall and CPU
seconds are recorded for runs this script trains.

Writes ``<name>.md`` / ``.json`` into ``--results``.

Usage (the issue's dataset: `vistac generate --n 3000 --noise 0.05 --seed 21 --split-by object`):
    python benchmarks/default_seeds.py --data D --out bench/seeds --seeds 0 1
    python benchmarks/default_seeds.py --data D --run 0=runs/r0 --run 1=runs/r1
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from learnbench import cpu_s, reference_entries, save

import vistac

METRIC = "angle_to_mean_median_deg"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", type=Path, required=True)
    ap.add_argument("--out", type=Path, default=Path("bench/seeds"), help="where runs are trained")
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1])
    ap.add_argument("--run", action="append", default=[], metavar="SEED=FOLDER",
                    help="an existing default-recipe run of that seed (not trained again)")
    ap.add_argument("--results", type=Path, default=Path("benchmarks/results"))
    ap.add_argument("--name", default="default_seeds")
    a = ap.parse_args()
    given = {int(k): Path(v) for k, _, v in (s.partition("=") for s in a.run)}
    rows, times = [], {}
    for seed in sorted(set(a.seeds) | set(given)):
        run = given.get(seed)
        if run is None:
            run = a.out / f"seed{seed}"
            t0, c0 = time.perf_counter(), cpu_s()
            vistac.train(vistac.TrainCfg(finger="both", seed=seed), data=a.data, out=run,
                         resume=(run / "config.json").exists())
            times[seed] = {"wall_s": time.perf_counter() - t0, "cpu_s": cpu_s() - c0}
        epochs = vistac.Run.open(run).config["train"]["epochs"]
        for tta in (True, False):
            ev = vistac.evaluate(run, tta="on" if tta else "off", no_plots=True,
                                 no_references=True, out=str(run / "eval" / f"seeds-tta{tta:d}"))
            rows.append({"seed": seed, "tta": tta, "epochs": epochs, "run": str(run),
                         **{f: ev.metrics[f][METRIC] for f in ("index", "thumb")}})
    refs = {e["label"]: {f: e["metrics"][f][METRIC] for f in ("index", "thumb")}
            for e in reference_entries(a.data)}
    lines = ["| predictor | seed | index (deg) | thumb (deg) |", "|---|---|---|---|"]
    for tta in (True, False):
        sel = [r for r in rows if r["tta"] == tta]
        label = "default recipe" + (" (as evaluated: mirrored view averaged)" if tta
                                    else ", --tta off")
        for r in sel:
            lines.append(f"| {label} | {r['seed']} | {r['index']:.3f} | {r['thumb']:.3f} |")
        lines.append(f"| {label} | mean | {np.mean([r['index'] for r in sel]):.3f} | "
                     f"{np.mean([r['thumb'] for r in sel]):.3f} |")
    for label, m in refs.items():
        lines.append(f"| {label} | - | {m['index']:.3f} | {m['thumb']:.3f} |")
    md = (f"The default recipe ({rows[0]['epochs']} epochs) on the test split of {a.data}, "
          "median angle to the cone mean. Training times of runs trained here: "
          + (", ".join(f"seed {s}: {t['wall_s']:.0f} s wall, {t['cpu_s']:.0f} CPU s"
                       for s, t in times.items()) or "none (existing runs)") + ".\n\n"
          + "\n".join(lines) + "\n")
    save(a.results, a.name, {"data": str(a.data), "rows": rows, "references": refs,
                             "train": times}, md, datasets=(a.data,))


if __name__ == "__main__":
    main()
