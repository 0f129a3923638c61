"""How spread the twin's labels are, against the study's, without training (issue 35).

A model that has learnt nothing predicts one direction for every image: the mean training label.
Its figures on the test split depend on the labels alone: how far apart the configurations'
directions lie (the grasp's approach and closing spreads) and how wide each configuration's cone
is (the sensor and the hand). The study's SmallConv stayed close to such a predictor (76.5 %
correct y, 26.4 % in cone), so this script scores the constant predictor on twins generated with
narrower and wider grasp spreads (same scene file, seed, size, objects and split) and sets it
beside the study's SmallConv and V3 rows, together with the spread of the labels themselves
(mean and std of the index label's angle in the y-z plane) and the MSE the cone means leave
(the within-configuration variance: no prediction scores below it).

Which spread reproduces the study's near-constant row says how far apart the study's
configurations were; whether a net trained on that twin then learns like the study's V3 is for
``study_replay.py`` on that twin to show.

Usage (datasets in ``--work``, reused by a rerun; about 70-150 s of generation each):

    .venv/bin/python benchmarks/study_spread.py
    .venv/bin/python benchmarks/study_spread.py --spreads 20,20 10,10 5,5
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import study_replay as replay
from studybench import twin_parser

from vistac.dataset import open_tables
from vistac.provenance import provenance
from vistac_learn.metrics.scoring import score
from vistac_sim.generate.config import GenerateCfg

KEYS = ("correct_y_pct", "in_cone_pct", "error_median_pct", "mse_mean",
        "angle_to_mean_median_deg")
HEAD = ("% correct y", "% in cone", "median err %", "mean MSE", "median ° to mean")
STUDY = {name: dict(zip(replay.STUDY_KEYS, replay.STUDY_ROWS[name], strict=True))
         for name in ("smallconv", "schoeconv100-v3-fc160")}


def twin(args: argparse.Namespace, approach: float, closing: float) -> Path:
    """The twin's dataset with these grasp spreads (`study_replay.dataset`, kept in --work)."""
    return replay.dataset(argparse.Namespace(**vars(args), approach_spread=approach,
                                             closing_spread=closing))


def measure(data: Path) -> dict:
    """The constant predictor's and the cone means' figures on the test split (index finger),
    and the index labels' angle (degrees, y over -z) over all configurations."""
    t = open_tables(data)
    test = t.rows("test")
    mean = t.mean_label("index")
    const = replay.constant_predictor(t)
    floor = score(mean[test], t, test, test, ("index",))
    angle = np.degrees(np.arctan2(mean[:, 0], -mean[:, 1]))
    return {"constant": {k: float(const[k]) for k in KEYS},
            "cone_means_mse": float(floor["index"]["mse_mean"]),
            "label_angle_mean_deg": float(angle.mean()),
            "label_angle_std_deg": float(angle.std()),
            "n_test": int(len(test))}


def fmt(key: str, v: float | None) -> str:
    """A table cell."""
    if v is None:
        return ""
    return f"{v:.1e}" if key == "mse_mean" else f"{v:.1f}"


def main(argv: list[str] | None = None) -> int:
    """Command-line entry."""
    p = twin_parser(__doc__, "study_spread", dataset=(1300, 64, (0.42, 0.06, 0.52)),
                    grasp=False)  # --spreads sets them
    p.add_argument("--spreads", nargs="+", default=["20,20", "10,10", "5,5", "3,3", "20,5",
                                                    "5,20"],
                   help="APPROACH,CLOSING grasp spreads in degrees")
    args = p.parse_args(argv)
    rows, datasets = [], []
    for text in args.spreads:
        try:
            a, c = (float(x) for x in text.split(","))
        except ValueError:
            raise SystemExit(f"--spreads {text!r}: write APPROACH,CLOSING in degrees") from None
        data = twin(args, a, c)
        datasets.append(data)
        rows.append({"approach_spread_deg": a, "closing_spread_deg": c, **measure(data)})
        print(f"{text}: {rows[-1]}", flush=True)
    head = ["predictor", "approach / closing spread °", *HEAD, "label angle mean ± std °",
            "cone means' MSE"]
    lines = ["| " + " | ".join(head) + " |", "|---" * len(head) + "|"]
    for r in rows:
        lines.append("| " + " | ".join([
            "constant (mean training label), twin",
            f"{r['approach_spread_deg']:g} / {r['closing_spread_deg']:g}",
            *(fmt(k, r["constant"][k]) for k in KEYS),
            f"{r['label_angle_mean_deg']:.1f} ± {r['label_angle_std_deg']:.1f}",
            fmt("mse_mean", r["cone_means_mse"])]) + " |")
    for name, label in (("smallconv", "SmallConv, the study (real)"),
                        ("schoeconv100-v3-fc160", "SchoeConv100-V3(FC160), the study (real)")):
        lines.append("| " + " | ".join([label, "", *(fmt(k, STUDY[name].get(k)) for k in KEYS),
                                        "", ""]) + " |")
    scene_grasp = GenerateCfg.from_file(args.scene).grasp
    md = "\n".join(lines) + (
        f"\n\nIndex finger, the test split ({rows[0]['n_test']} configurations of held-out "
        f"objects) of twins of {args.n} configurations of {args.n_objects} objects (seed "
        f"{args.data_seed}, scene `{Path(args.scene).name}`), one per pair of grasp spreads "
        f"(`GraspCfg.approach_spread_deg` / `closing_spread_deg`; the scene file's are "
        f"{scene_grasp.approach_spread_deg:g} / {scene_grasp.closing_spread_deg:g}). "
        "Constant: every test configuration predicted as the mean training label, i.e. a model "
        "that learnt nothing. Label angle: atan2(y, -z) of each configuration's mean index "
        "label. Cone means' MSE: the configurations' own mean labels as predictions, the MSE "
        "no model goes below.")
    result = {"provenance": provenance(datasets), "settings": vars(args), "rows": rows,
              "table": md}
    out = Path(args.results)
    out.mkdir(parents=True, exist_ok=True)
    (out / f"{args.name}.json").write_text(json.dumps(result, indent=2) + "\n")
    (out / f"{args.name}.md").write_text(f"# The twin's label spread against the study's\n\n"
                                         f"{md}\n")
    print(md, flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
