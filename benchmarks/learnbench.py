"""Shared pieces of the learning benchmarks: datasets, resumable train-and-score entries, tables.

Every entry is a training run in ``<out>/runs/<slug>`` made by
`vistac_learn.train.loop.train_run_folder` and scored on the test split by `evaluate_run`; a
rerun skips finished runs and resumes unfinished ones, so a benchmark killed half-way continues
where it stopped.
"""

from __future__ import annotations

import csv
import json
import re
import resource
import time
from pathlib import Path

import numpy as np

import vistac
from vistac.dataset import FINGERS, SplitCfg, open_tables
from vistac.provenance import provenance
from vistac_learn.evaluate.config import EvaluateCfg
from vistac_learn.evaluate.references import LABELS, references
from vistac_learn.evaluate.run import evaluate_baseline, evaluate_run
from vistac_learn.metrics import cone_metrics
from vistac_learn.train.config import protocol_cfg
from vistac_learn.train.loop import train_run_folder
from vistac_sim.generate.config import GenerateCfg

# The default recipe without what averages a one-sided lean of the labels away: mirroring (in
# training and at test time) and the simulator's contact targets (docs/learner.md, "When the
# labels lean to one side"). The study twin's finger pull leans every index label ~8 degrees.
LEAN_RECIPE = {"mirror": False, "tta": False, "aux_weight": 0.0}
LEAN_LABEL = "default recipe, no mirror, no contact targets"

COLUMNS = (("° to mean", "angle_to_mean_median_deg"), ("% in cone", "in_cone_pct"),
           ("% correct y", "correct_y_pct"), ("median err %", "error_median_pct"),
           ("median inacc. mean %", "inacc_mean_median_pct"))


def ensure_dataset(path: Path, cfg: GenerateCfg) -> Path:
    """`vistac.generate(cfg, path)` unless a complete dataset is there (resumed if partial)."""
    man = path / "manifest.json"
    if man.exists() and json.loads(man.read_text()).get("complete"):
        return path
    t0 = time.perf_counter()
    vistac.generate(cfg, path, resume=(path / ".partial").exists())
    print(f"generated {path} in {time.perf_counter() - t0:.0f} s", flush=True)
    return path


def headline_data(n: int, seed: int = 0, preset: str = "clean") -> GenerateCfg:
    """The learning benchmarks' dataset: `vistac generate --n N --noise 0.05 --split-by object
    --seed S` (``--preset P`` when not clean)."""
    return GenerateCfg.from_preset(preset, noise=0.05, n=n, seed=seed,
                                   split=SplitCfg(by="object"))


def slug(label: str) -> str:
    """A folder name for an entry's label."""
    return re.sub(r"[^a-z0-9]+", "-", label.lower()).strip("-")


def _epoch_rows(run: Path) -> list[dict]:
    path = run / "metrics.csv"
    if not path.exists():
        return []
    with path.open() as fh:
        return list(csv.DictReader(fh))


def finished_run(out: Path, label: str, epochs: int) -> bool:
    """Whether `run_entry(data, out, label, ...)` has trained its `epochs` (it would only score)."""
    return len(_epoch_rows(out / "runs" / slug(label))) >= epochs


def cpu_s() -> float:
    """CPU seconds (user + system) of this process and its finished children."""
    own, kids = (resource.getrusage(w) for w in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN))
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def timed_runner(path: Path):
    """A runner of an experiment's training jobs (`vistac.label_noise(..., runner=)`,
    `vistac.sim2real`) that adds each job's CPU seconds (training and its scorings) to the JSON
    `path`, keyed by the job's run folder (resolved): a job resumed after an interruption adds
    its new session (one killed with SIGKILL loses its unfinished part)."""
    from vistac_learn.train.job import LocalJobRunner, run_job

    def job(cfg):
        c0 = cpu_s()
        try:
            return run_job(cfg)
        finally:
            spent = json.loads(path.read_text()) if path.exists() else {}
            key = str(Path(cfg.train.out).resolve())
            spent[key] = spent.get(key, 0.0) + cpu_s() - c0
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(json.dumps(spent, indent=1))

    return LocalJobRunner(job)


def cell_cpu_s(path: Path, run: str) -> float | None:
    """The CPU seconds `timed_runner` recorded in `path` for a cell's run folder."""
    spent = json.loads(path.read_text()) if path.exists() else {}
    return spent.get(str(Path(run).resolve())) if run else None


def run_entry(data: Path, out: Path, label: str, protocol: str = "default",
              progress: bool = True, **changes) -> dict:
    """Train (or finish training) one run and score its best epoch on the test split.

    The wall and CPU seconds of the `train_run_folder` calls (locating fingertips not yet cached
    included) add up in ``<run>/train_time.json`` over resumed sessions: on a shared machine
    the CPU seconds are the comparable figure.
    """
    run = out / "runs" / slug(label)
    cfg = protocol_cfg(protocol, str(data), str(run), device="cpu", **changes)
    timing_path = run / "train_time.json"
    if len(_epoch_rows(run)) < cfg.epochs:
        print(f"== {label}: training", flush=True)
        t0, c0 = time.perf_counter(), cpu_s()
        train_run_folder(cfg, resume=(run / "checkpoints" / "last.pt").exists(), progress=progress)
        spent = json.loads(timing_path.read_text()) if timing_path.exists() else {}
        timing_path.write_text(json.dumps({
            "wall_s": spent.get("wall_s", 0.0) + time.perf_counter() - t0,
            "cpu_s": spent.get("cpu_s", 0.0) + cpu_s() - c0,
            "sessions": spent.get("sessions", 0) + 1}))
    timing = json.loads(timing_path.read_text()) if timing_path.exists() else {}
    scored = run / "eval" / "test" / "metrics.json"
    best = run / "checkpoints" / "best.pt"
    if scored.exists() and scored.stat().st_mtime > best.stat().st_mtime:
        res = json.loads(scored.read_text())
    else:
        res = evaluate_run(EvaluateCfg(run=str(run), no_plots=True, device="cpu",
                                       max_missing_pct=cfg.max_missing_pct))
    rows = _epoch_rows(run)
    meta = json.loads((run / "config.json").read_text())
    return {"label": label, "kind": "model", "protocol": protocol, "model": cfg.model,
            "variant": cfg.variant, "fingers": res["fingers"], "metrics": res["metrics"],
            "macs": meta["model"]["macs_per_sample"], "params": meta["model"]["params"],
            "epochs": len(rows), "best_epoch": res["epoch"],
            "train_s": float(sum(float(r["train_s"]) for r in rows)),
            "train_s_per_epoch": float(np.mean([float(r["train_s"]) for r in rows])),
            "images_per_s": res["images_per_s"],
            "train_wall_s": timing.get("wall_s"), "train_cpu_s": timing.get("cpu_s"),
            "n_train": meta["dataset"]["n_train_configs"], "run": str(run)}


def baseline_entry(data: Path, out: Path, fingers=FINGERS) -> dict:
    """The geometric baseline on the unrotated test images."""
    finger = "both" if len(fingers) == 2 else fingers[0]
    res = evaluate_baseline(EvaluateCfg(baseline="geometric", data=str(data), finger=finger,
                                        rotations="none", no_plots=True), out / "baseline")
    return {"label": "geometric baseline (non-learned)", "kind": "baseline",
            "fingers": res["fingers"], "metrics": res["metrics"], "macs": None,
            "train_s": 0.0, "images_per_s": res["images_per_s"], "failures": res["failures"]}


def reference_entries(data: Path, fingers=FINGERS) -> list[dict]:
    """The noise floor and the pinch baseline on the whole test split (unrotated images; the
    pinch summary is cached in the dataset's ``cache/``), or none for a dataset without the
    simulator's clean forces."""
    t = open_tables(data)
    refs = references(t, t.rows("test"), tuple(fingers))
    if refs is None:
        return []
    return [{"label": LABELS[k], "kind": "reference", "fingers": list(fingers),
             "metrics": refs[k]["metrics"], "macs": None, "train_s": 0.0} for k in LABELS]


def mean_entry(data: Path, fingers=FINGERS) -> dict:
    """Predicting the training split's mean label for every test configuration."""
    t = open_tables(data)
    rows = t.rows("test")
    metrics = {}
    for f in fingers:
        mean = t.mean_label(f)[t.rows("train")].mean(axis=0)
        res = cone_metrics(np.tile(mean, (len(rows), 1)), np.arange(len(rows)),
                           [t.cones[f][r] for r in rows])
        metrics[f] = {k: float(v) for k, v in res.items() if np.isscalar(v)}
    return {"label": "mean label (constant)", "kind": "constant", "fingers": list(fingers),
            "metrics": metrics, "macs": None, "train_s": 0.0}


def fmt(v) -> str:
    """A table cell."""
    if v is None or (isinstance(v, float) and not np.isfinite(v)):
        return "-"
    if isinstance(v, int | np.integer):
        return str(v)
    return f"{v:.3g}" if abs(v) < 1000 else f"{v:.0f}"


def table(entries: list[dict], extra: tuple[tuple[str, str], ...] = ()) -> str:
    """Markdown: one row per entry and finger; the study's and the angular columns, then
    `extra` (header, entry key) columns."""
    head = ["model / setting", "finger", *(h for h, _ in COLUMNS), *(h for h, _ in extra)]
    lines = ["| " + " | ".join(head) + " |", "|---" * len(head) + "|"]
    for e in entries:
        for f in e["fingers"]:
            m = e["metrics"][f]
            cells = [e["label"], f, *(fmt(m.get(k)) for _, k in COLUMNS),
                     *(f"{e[k] / 1e6:.1f} M" if k == "macs" and e.get(k) else fmt(e.get(k))
                       for _, k in extra)]
            lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def save(out: Path, name: str, result: dict, markdown: str, datasets=()) -> None:
    """Write ``<name>.json`` (with its `provenance`: command, commit, date, machine and the
    fingerprints of `datasets`) and ``<name>.md`` into `out` and print the table."""
    result = {**result, "provenance": provenance([d for d in datasets if d is not None])}
    out.mkdir(parents=True, exist_ok=True)
    (out / f"{name}.json").write_text(json.dumps(result, indent=2))
    (out / f"{name}.md").write_text(markdown + "\n")
    print(markdown, flush=True)
