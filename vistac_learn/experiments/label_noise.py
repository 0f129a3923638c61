"""`vistac experiment label-noise`: how accuracy degrades with label noise.

The same configurations (images, splits) get labels drawn by the generator's own noise model
(`vistac.noise.relative_force_noise`, the ``--noise`` of `vistac generate`) from the dataset's
clean forces, at each level and seed: nothing is simulated again. The noise of (level, seed) is
drawn from ``numpy.random.default_rng([STREAM, seed, round(level * 1e6)])`` over every press of
the source dataset in (config_id, repeat) order, so it is reproducible. Each noisy dataset is a
folder under ``--out`` (``data/noise-<level>-seed-<seed>``) sharing the source's manifest,
configuration table and images (so its fingertip cache too) with new presses; ``data/clean``
holds the clean labels (one press per configuration, a cone of zero width).

Per level and seed, one model is trained (and selected) on the noisy labels and scored on the
test split against the clean labels and against the noisy cones.

Outputs in ``--out``: ``cells.csv``, ``results.csv`` (mean and std over seeds per level),
``report.md``, ``label_noise.png`` (error bars), the runs under ``runs/``.
"""

from __future__ import annotations

import dataclasses
import os
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from vistac.config import Config, param
from vistac.dataset import atomic_write_json, open_tables, press_row, unit_labels, write_table
from vistac.dataset.schema import (
    CONFIGS,
    FINGERS,
    IMAGES,
    MANIFEST,
    MASKS,
    PRESSES,
    clean_force_columns,
)
from vistac.errors import UserError
from vistac.folder_lock import hold
from vistac.noise import relative_force_noise
from vistac_learn.experiments import cells as C
from vistac_learn.train.config import TrainCfg
from vistac_learn.train.job import JobCfg, JobResult, ScoreCfg

KIND = "label-noise"
STREAM = 9  # the label-noise stream of the seed sequence
METRICS = ("clean_angle_deg", "noisy_angle_deg", "noisy_in_cone_pct", "val_angle_deg",
           "label_angle_deg")


@dataclass(frozen=True)
class LabelNoiseCfg(Config):
    """The settings of a label-noise experiment (the runs' come from the base `TrainCfg`)."""

    data: str = param(help="dataset with clean forces (force_clean_* columns)")
    out: str = param(help="experiment folder")
    levels: tuple[float, ...] = param((0.0, 0.02, 0.05, 0.1, 0.2), ge=0, le=10,
                                      help="relative std of the force noise (as --noise of "
                                      "`vistac generate`)", distinct="level")
    seeds: int = param(3, ge=1, le=1000, help="seeds per level (0 .. N-1): noise and training")


def noisy_presses(configs: pd.DataFrame, presses: pd.DataFrame, level: float,
                  seed: int) -> pd.DataFrame:
    """Presses whose forces are the clean forces with the noise of (level, seed).

    Args:
        configs: The configuration table (with ``force_clean_<finger>_x|y|z``).
        presses: The source presses (their ``config_id`` and ``repeat`` are kept).
        level: Relative noise std (0: the clean forces).
        seed: Seed of the draw.

    Returns:
        The presses table (measured forces and unit labels replaced).
    """
    order = presses.sort_values(["config_id", "repeat"], kind="stable")
    clean = clean_forces(configs).loc[order["config_id"].to_numpy()].to_numpy().reshape(-1, 2, 3)
    rng = np.random.default_rng([STREAM, seed, int(round(level * 1e6))])
    forces = relative_force_noise(clean, level, rng)
    labels = unit_labels(forces)
    return pd.DataFrame([press_row(int(c), int(r), forces[i], labels[i]) for i, (c, r) in
                         enumerate(zip(order["config_id"], order["repeat"], strict=True))])


def clean_forces(configs: pd.DataFrame) -> pd.DataFrame:
    """(config_id -> 6 columns) clean forces, index then thumb, x|y|z."""
    cols = [c for f in FINGERS for c in clean_force_columns(f)]
    return configs.set_index("config_id")[cols].astype(float)


def derive_dataset(source: Path, folder: Path, presses: pd.DataFrame, note: dict) -> None:
    """A dataset that is `source` with other presses (manifest, configs and images shared).

    The manifest and configuration table are byte copies, so the dataset's image fingerprint
    (and fingertip cache) is the source's (its fingerprint, which covers the labels, is not);
    ``label_noise.json`` says what was changed. Written
    manifest last: a folder without it is redone.
    """
    if (folder / MANIFEST).exists():
        return
    folder.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(source / CONFIGS, folder / CONFIGS)
    for name in (IMAGES, MASKS):  # masks/ too where the source has them (its manifest says so)
        link = folder / name
        if (source / name).is_dir() and not link.is_symlink():
            os.symlink((source / name).resolve(), link, target_is_directory=True)
    write_table(folder / PRESSES, presses)
    atomic_write_json(folder / "label_noise.json", note)
    shutil.copyfile(source / MANIFEST, folder / MANIFEST)


def _label_angle(tables_cones: dict, clean: np.ndarray, rows: np.ndarray) -> float:
    """Median angle (deg) between each noisy press label and its configuration's clean label."""
    angles = []
    for k, f in enumerate(FINGERS):
        for r in rows:
            c = clean[r, k]
            cos = np.clip(tables_cones[f][r] @ c, -1.0, 1.0)
            angles.append(np.degrees(np.arccos(cos)))
    return float(np.median(np.concatenate(angles)))


def prepare_data(cfg: LabelNoiseCfg) -> dict[tuple[float, int], float]:
    """Write the clean and the noisy datasets under ``out/data`` (those missing).

    Returns:
        (level, seed) -> median angle between the noisy and the clean test labels (deg).

    Raises:
        UserError: an unreadable dataset.
    """
    source = Path(cfg.data)
    tables = open_tables(source)
    data = Path(cfg.out) / "data"
    clean_presses = tables.presses[tables.presses["repeat"] == tables.presses["repeat"].min()]
    derive_dataset(source, data / "clean", noisy_presses(tables.configs, clean_presses, 0.0, 0),
                   {"source": str(source), "level": 0.0, "what": "clean labels"})
    clean = unit_labels(clean_forces(tables.configs).loc[tables.configs["config_id"]]
                        .to_numpy().reshape(-1, 2, 3))
    test = tables.rows("test")
    angles = {}
    for level in cfg.levels:
        for s in range(cfg.seeds):
            folder = data / _name(level, s)
            presses = noisy_presses(tables.configs, tables.presses, level, s)
            derive_dataset(source, folder, presses, {
                "source": str(source), "level": level, "seed": s,
                "model": "vistac.noise.relative_force_noise", "stream": STREAM})
            angles[(level, s)] = _label_angle(open_tables(folder).cones, clean, test)
    return angles


def _name(level: float, seed: int) -> str:
    return f"noise-{level:g}-seed-{seed}"


def make_cells(cfg: LabelNoiseCfg, base: TrainCfg) -> list[C.Cell]:
    """Every cell, in report order (`base`'s data, out and seed are replaced)."""
    out = Path(cfg.out).absolute()
    cache = base.cache_dir or str(Path(cfg.data) / "cache")  # one image fingerprint: one cache
    clean = ScoreCfg("clean", "test", data=str(out / "data" / "clean"))
    cells = []
    for level in sorted(cfg.levels):
        for s in range(cfg.seeds):
            run = dataclasses.replace(
                base, data=str(out / "data" / _name(level, s)),
                out=str(out / "runs" / f"noise-{level:g}" / f"seed-{s}"), seed=s,
                cache_dir=cache)
            cells.append(C.Cell(f"noise/{level:g}/{s}", {"level": level, "seed": s},
                                JobCfg(run, (clean, ScoreCfg("noisy", "test")))))
    return cells


def measure(res: JobResult, label_angle: float) -> dict[str, float]:
    """A finished cell's numbers (angles: median angle to the cone mean, deg, mean of fingers;
    `label_angle`: that of its noisy labels to the clean ones)."""
    return {"clean_angle_deg": res.score("clean"), "noisy_angle_deg": res.score("noisy"),
            "noisy_in_cone_pct": res.score("noisy", "in_cone_pct"),
            "val_angle_deg": res.objective, "label_angle_deg": label_angle}


def run_label_noise(cfg: LabelNoiseCfg, base: TrainCfg, runner: Any = None,
                    max_cells: int | None = None,
                    progress: bool = True) -> list[dict[str, Any]]:
    """Run (or continue) the experiment in ``cfg.out``; return the rows of ``cells.csv``.

    Args:
        cfg: The experiment's settings (the dataset path absolute).
        base: The runs' training settings (data, out and seed are set per cell).
        runner: Runs the training jobs (default `LocalJobRunner`).
        max_cells: Stop after this many new cells (a rerun continues).
        progress: Show a progress bar.

    Raises:
        UserError: an --out holding another experiment or other settings, bad data.
    """
    with hold(cfg.out, "experiment"):
        out = C.open_experiment(cfg, base, KIND)
        angles = prepare_data(cfg)
        cells = make_cells(cfg, base)

        def measure_cell(cell: C.Cell, res: JobResult) -> dict[str, float]:
            return measure(res, angles[(cell.fields["level"], cell.fields["seed"])])

        def on_rows(rows: list[dict[str, Any]]) -> None:
            write_outputs(out, cfg, base, rows)

        return C.run_cells(out, cells, METRICS, measure_cell, on_rows, runner, max_cells, progress)


def write_outputs(out: Path, cfg: LabelNoiseCfg, base: TrainCfg,
                  rows: list[dict[str, Any]]) -> None:
    """results.csv, report.md and label_noise.png from the finished rows."""
    from vistac_learn.experiments.plots import plot_label_noise

    summary = C.summarise(rows, ("level",), METRICS)
    cols = ["level", "n", *(f"{m}_{s}" for m in METRICS for s in ("mean", "std"))]
    C.write_rows(out / "results.csv", summary, cols)
    plot_label_noise(summary, out / "label_noise.png")
    (out / "report.md").write_text(report(cfg, base, summary, len(rows)))


def report(cfg: LabelNoiseCfg, base: TrainCfg, summary: list[dict], n_rows: int) -> str:
    """The markdown report: settings, table, how accuracy degrades."""
    lines = [
        "# Label noise: accuracy against the level of force noise in the labels", "",
        f"- data: `{cfg.data}` (labels redrawn from its clean forces by "
        "`vistac.noise.relative_force_noise`, the generator's `--noise` model)",
        f"- levels (relative std): {', '.join(f'{v:g}' for v in cfg.levels)}; seeds: "
        f"{cfg.seeds}",
        f"- training: model {base.model}, view {base.variant}, fingers {base.finger}, "
        f"{base.epochs} epochs, batch {base.batch_size}, lr {base.lr:g}",
        f"- cells finished: {n_rows} of {len(cfg.levels) * cfg.seeds}", "",
        "Test split; angle: median angle to the cone mean (deg, mean of the fingers; lower is "
        "better); mean ± std over seeds. Label angle: median angle between a noisy test label "
        "and its clean label.", "",
        "| noise level | seeds | label angle (deg) | angle to clean label (deg) | angle to noisy "
        "cone mean (deg) | in noisy cone (%) |", "|---|---|---|---|---|---|"]
    for s in summary:
        lines.append(
            f"| {s['level']:g} | {s['n']} | "
            f"{C.pm(s['label_angle_deg_mean'], s['label_angle_deg_std'])} | "
            f"{C.pm(s['clean_angle_deg_mean'], s['clean_angle_deg_std'])} | "
            f"{C.pm(s['noisy_angle_deg_mean'], s['noisy_angle_deg_std'])} | "
            f"{C.pm(s['noisy_in_cone_pct_mean'], s['noisy_in_cone_pct_std'])} |")
    lines += ["", finding(summary), "", "![label noise](label_noise.png)", ""]
    return "\n".join(lines)


def finding(summary: list[dict]) -> str:
    """One sentence: how the angle to the clean label changes from the lowest to the highest
    level, and whether it grows with every step."""
    done = sorted((s for s in summary if s["n"]), key=lambda s: s["level"])
    if len(done) < 2:
        return "No finding yet: fewer than two levels have finished."
    lo, hi = done[0], done[-1]
    a, b = lo["clean_angle_deg_mean"], hi["clean_angle_deg_mean"]
    means = [s["clean_angle_deg_mean"] for s in done]
    steady = all(y >= x for x, y in zip(means, means[1:], strict=False))
    label = hi["label_angle_deg_mean"]
    scale = "far smaller than" if 2 * abs(b - a) < label else "of the order of"
    shape = ("growing at every step" if steady else "not monotone over the levels (compare "
             "the steps with the spread over seeds)")
    return (f"**Finding**: from noise level {lo['level']:g} to {hi['level']:g} the median angle "
            f"to the clean label goes from {C.pm(a, lo['clean_angle_deg_std'])} to "
            f"{C.pm(b, hi['clean_angle_deg_std'])} deg ({b - a:+.1f} deg, "
            f"{(b / a - 1) * 100 if a > 0 else float('nan'):+.0f} %), {shape}. At level "
            f"{hi['level']:g} the noisy labels themselves lie {label:.1f} deg from the clean "
            f"ones: the model's loss of accuracy is {scale} the noise in its labels.")


def resolved(cfg: LabelNoiseCfg) -> LabelNoiseCfg:
    """The config with an absolute dataset path."""
    return dataclasses.replace(cfg, data=str(Path(cfg.data).resolve()))


def check_inputs(cfg: LabelNoiseCfg) -> None:
    """Before any work: the dataset is complete and has finite clean forces.

    Raises:
        UserError: naming --data.
    """
    source = Path(cfg.data)
    try:
        tables = open_tables(source)
    except UserError as exc:
        raise UserError(f"--data {exc}") from None
    cols = [c for f in FINGERS for c in clean_force_columns(f)]
    missing = [c for c in cols if c not in tables.configs]
    if missing:
        raise UserError(f"--data {source}: {CONFIGS} has no clean forces ({missing[0]}, ...); "
                        "label noise is drawn from the clean forces of a generated dataset")
    if not np.isfinite(tables.configs[cols].to_numpy(float)).all():
        raise UserError(f"--data {source}: {CONFIGS}: non-finite clean forces")
