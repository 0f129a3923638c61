"""A cheap calibration aid for the twin (issue 35): predict, without training, what a finished
V3 run would score on candidate twins, to choose the next scene file to verify with real runs.

A model's error is, to first order, a turn of its prediction away from the configuration's mean
label; what the twin's scene changes is the cones it is scored against (their centre and width:
force noise, finger pull, the FTS-3). So: take each test prediction of a finished run
(``<run>/eval/test/predictions.parquet``), its signed angle to its configuration's mean label and
its length, and transplant it onto the same configuration's cone in each candidate's dataset
(generated from the same seed, size, objects and split as the run's dataset, read from its
manifest, so configuration ids and images match and only the labels differ): the candidate's
mean label turned by that angle, at that length. The transplanted predictions are then scored
as `vistac evaluate` scores (% correct y, % in cone, MSE, the study's columns). The run's own
dataset transplanted onto itself reproduces the run's figures (a check, the first row).

Not a replacement for training: a model trained on other labels learns other mean directions;
what this predicts is the effect of the cones alone. Verify the chosen candidate with real runs
(``study_replay.py --scene <work>/scenes/<name>.yaml``).

Candidates are effect changes over the twin's scene file, ``NAME=KEY=VALUE[,KEY=VALUE]`` with
dotted keys and JSON values, e.g. ``noise02=noise=0.02`` or
``pull=finger_pull.spread=0.1,finger_pull.config_spread=0.15``.

Writes ``<name>.json|md|png``; datasets are kept in ``--work`` (a rerun reuses them).

Usage:
    .venv/bin/python benchmarks/study_calibrate.py --run RUN
    .venv/bin/python benchmarks/study_calibrate.py --run RUN --candidates noise02=noise=0.02
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
import study_replay as replay  # noqa: E402
from studybench import V3, scene_file, twin_parser  # noqa: E402

from vistac.dataset import open_tables  # noqa: E402
from vistac.provenance import provenance  # noqa: E402
from vistac_learn.metrics.scoring import score  # noqa: E402
from vistac_sim.effects.presets import load_scene  # noqa: E402

DEFAULT_CANDIDATES = ("noise 0.02=noise=0.02", "noise 0.05=noise=0.05", "noise 0.1=noise=0.1",
                      "pull spread 0.1=finger_pull.spread=0.1,finger_pull.config_spread=0.15",
                      "pull spread 0.02=finger_pull.spread=0.02,finger_pull.config_spread=0.04",
                      "no finger pull=finger_pull=false")


def parse_candidate(text: str, base: Path) -> tuple[str, dict]:
    """``NAME=KEY=VALUE[,KEY=VALUE]`` -> (name, effect changes), a dotted key setting a field of
    the twin's effect table (kept otherwise)."""
    name, _, spec = text.partition("=")
    effects = load_scene(base).get("effects", {})
    changes: dict = {}
    for item in filter(None, spec.split(",")):
        key, _, value = item.partition("=")
        if not key or not value:
            raise SystemExit(f"--candidates {text!r}: write NAME=KEY=VALUE[,KEY=VALUE]")
        value = json.loads(value)
        top, _, field = key.partition(".")
        if not field:
            changes[top] = value
            continue
        table = changes.get(top)
        if not isinstance(table, dict):
            table = dict(effects.get(top) or {})
        changes[top] = {**table, field: value}
    return name, changes


def transplant(pred: pd.DataFrame, run_tables, tables) -> tuple[np.ndarray, np.ndarray]:
    """The index predictions turned from the run's mean labels onto `tables`' (same
    configuration ids): (predictions (M, 2), row of each in `tables`)."""
    src_row = {c: i for i, c in enumerate(run_tables.configs["config_id"].to_numpy())}
    dst_row = {c: i for i, c in enumerate(tables.configs["config_id"].to_numpy())}
    missing = set(pred["config_id"]) - set(dst_row)
    if missing:
        raise SystemExit(f"{len(missing)} test configurations are not in the candidate's "
                         "dataset: generate it with the run's seed, size, objects and split")
    p = pred[["pred_index_y", "pred_index_z"]].to_numpy(float)
    src = run_tables.mean_label("index")[[src_row[c] for c in pred["config_id"]]]
    item_row = np.array([dst_row[c] for c in pred["config_id"]])
    dst = tables.mean_label("index")[item_row]
    turn = np.arctan2(p[:, 0], p[:, 1]) - np.arctan2(src[:, 0], src[:, 1])
    angle = np.arctan2(dst[:, 0], dst[:, 1]) + turn
    length = np.hypot(p[:, 0], p[:, 1])
    return np.stack([length * np.sin(angle), length * np.cos(angle)], axis=1), item_row


SAME = ("object_id", "object_x", "object_y", "object_yaw", "target_index_x", "target_index_y")
COLUMNS = (*replay.STUDY_KEYS, "angle_to_mean_median_deg", "same_config_pct")


def predicted(pred: pd.DataFrame, run_tables, tables) -> dict:
    """The study's columns (and the angle to the mean) of the transplanted predictions, and
    the % of their configurations whose object, pose and index target match the run's."""
    p, item_row = transplant(pred, run_tables, tables)
    m = score(p, tables, np.unique(item_row), item_row, ("index",))["index"]
    ids = pd.Index(np.unique(pred["config_id"]))
    a, b = (t.configs.set_index("config_id").loc[ids, list(SAME)] for t in (run_tables, tables))
    same = float(100 * np.mean((a.astype(str) == b.astype(str)).all(axis=1)))
    return {**{k: float(m[k]) for k in COLUMNS[:-1]}, "same_config_pct": same}


def plot(rows: list[dict], path: Path) -> None:
    """Predicted % correct y and % in cone per candidate, the study's V3 figures as lines."""
    fig, ax = plt.subplots(figsize=(9, 4.5))
    study = dict(zip(replay.STUDY_KEYS, replay.STUDY_ROWS[V3], strict=True))
    for j, key in enumerate(("correct_y_pct", "in_cone_pct")):
        colour = ("tab:blue", "tab:orange")[j]
        ax.plot([i + (j - 0.5) * 0.3 for i in range(len(rows))], [r["metrics"][key]
                                                                  for r in rows],
                "o", color=colour, label=("% correct y", "% in cone")[j])
        ax.axhline(study[key], color=colour, ls=":", lw=1)
        ax.axhspan(study[key] - 5, study[key] + 5, color=colour, alpha=0.08)
    ax.set_xticks(range(len(rows)), [r["label"] for r in rows], rotation=20, ha="right",
                  fontsize=8)
    ax.set_ylim(0, 100)
    ax.set_ylabel("% (index finger, predicted)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, title="dotted: the study's V3 (band: ± 5)", title_fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def calibrate(args: argparse.Namespace) -> dict:
    """Score the run's transplanted predictions on every candidate's cones."""
    run = Path(args.run)
    pred_path = run / "eval" / "test" / "predictions.parquet"
    if not pred_path.exists():
        raise SystemExit(f"{pred_path}: missing (score the run: vistac evaluate --run {run})")
    pred = pd.read_parquet(pred_path)
    meta = json.loads((run / "config.json").read_text())
    run_data = Path(meta["dataset"]["path"])
    run_tables = open_tables(run_data)
    made = json.loads((run_data / "manifest.json").read_text())["config"]
    same = {"n": made["n"], "data_seed": made["seed"], "split": made["split"]["fractions"],
            "n_objects": made["objects"]["n_objects"]}  # the run's dataset, another scene
    rows = [{"label": "the run itself (check)", "changes": None,
             "metrics": predicted(pred, run_tables, run_tables)}]
    work = Path(args.work)
    datasets = [run_data]
    for text in args.candidates:
        name, changes = parse_candidate(text, Path(args.scene))
        folder = "".join(c if c.isalnum() else "_" for c in name)
        scene = scene_file(Path(args.scene), folder, changes, work)
        data = replay.dataset(argparse.Namespace(**same, scene=str(scene), work=str(work / folder)))
        datasets.append(data)
        rows.append({"label": name, "changes": changes, "scene": str(scene),
                     "metrics": predicted(pred, run_tables, open_tables(data))})
        print(f"{name}: {rows[-1]['metrics']}", flush=True)
    head = ["twin (cones)", *(h for h, _ in replay.STUDY_COLUMNS), "median ° to mean",
            "% same configurations"]
    lines = ["| " + " | ".join(head) + " |", "|---" * len(head) + "|"]
    study = dict(zip(replay.STUDY_KEYS, replay.STUDY_ROWS[V3], strict=True))
    for r in [*rows, {"label": "the study's V3 (real)", "metrics": study}]:
        lines.append("| " + " | ".join([r["label"], *(replay.fmt(k, r["metrics"].get(k))
                                                        for k in COLUMNS)])
                     + " |")
    md = "\n".join(lines) + (
        f"\n\nIndex finger. Predicted, not trained: the test predictions of `{run}` "
        f"({len(pred)} predictions), each turned from its configuration's mean label onto the "
        "same configuration's mean label in the candidate's dataset (same seed, size, objects "
        "and split, only the scene's effects changed) and scored against its cone. The first "
        "row transplants onto the run's own dataset: the run's figures. % same configurations: "
        "the test configurations whose object, pose and index target are the run's (below "
        "100, the transplant mixes configurations: read that row with care).")
    result = {"provenance": provenance(datasets), "run": str(run),
              "settings": {k: str(v) if isinstance(v, Path) else v for k, v in vars(args).items()},
              "rows": rows, "table": md}
    out = Path(args.results)
    out.mkdir(parents=True, exist_ok=True)
    (out / f"{args.name}.json").write_text(json.dumps(result, indent=2) + "\n")
    (out / f"{args.name}.md").write_text(f"# Calibrating the twin without training\n\n{md}\n")
    plot(rows, out / f"{args.name}.png")
    print(md, flush=True)
    return result


def main(argv: list[str] | None = None) -> int:
    """Command-line entry."""
    p = twin_parser(__doc__, "study_calibrate")
    p.add_argument("--run", required=True, help="a finished, scored V3 run on the twin")
    p.add_argument("--candidates", nargs="+", default=list(DEFAULT_CANDIDATES),
                   help="NAME=KEY=VALUE[,KEY=VALUE] effect changes over --scene")
    args = p.parse_args(argv)
    calibrate(args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
