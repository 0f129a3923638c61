"""The Python API: every `vistac` command as a function that returns what it made.

```python
import vistac
ds  = vistac.generate(vistac.GenerateCfg(n=200, seed=1), out="data/d")     # -> vistac.Dataset
ds  = vistac.open_dataset("data/d")                                         # read back
run = vistac.train(vistac.TrainCfg(epochs=2), data="data/d", out="runs/r")  # -> vistac.Run
ev  = vistac.evaluate(run)        # or a run folder; ev.metrics == metrics.json's "metrics"
```

The `vistac` command is a thin layer over these functions: it turns options into the same
configs, calls the same function and prints its summary. Hence:

- configs are complete where they are made (`GenerateCfg.from_preset`, `.from_file`,
  `TrainCfg.from_protocol`) and check themselves;
- bad input raises `vistac.errors.UserError` carrying the one line the CLI prints (e.g.
  ``--data ...``), except a config that its declaration does not allow: its
  `vistac.config.ConfigError` names the field (``model: ...``) where the CLI names the option
  (``--model: ...``);
- nothing is written to stdout; ``progress=True`` draws progress bars on stderr;
- the same config and seed give the same bytes from Python and from the CLI.

This module imports neither MuJoCo nor torch; each function imports its half when called.
Generation with worker processes starts a fork server that does not import the caller's main
module, so the default ``workers`` works from a script (with or without the
``if __name__ == "__main__":`` guard), ``python -c``, a script read on stdin, `runpy` and a
notebook alike (tests/core/test_entry_points.py).
"""

from __future__ import annotations

import dataclasses
import os
import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from vistac.api_args import (
    check_max_cells,
    config_arg,
    count_arg,
    folder_arg,
    optional_config_arg,
)
from vistac.errors import UserError, brief
from vistac.folder_lock import hold
from vistac.outputs import Dataset, Evaluation, Report, Run

if TYPE_CHECKING:  # the configs live beside the code that uses them
    from vistac.dataset.ingest.config import IngestCfg, IngestSources
    from vistac.engine import EngineCfg
    from vistac_learn.evaluate.config import EvaluateCfg
    from vistac_learn.experiments.label_noise import LabelNoiseCfg
    from vistac_learn.experiments.sim2real import Sim2RealCfg
    from vistac_learn.train.config import TrainCfg
    from vistac_learn.tune.engines import TrialCfg
    from vistac_sim.generate.config import GenerateCfg


# ------------------------------------------------------------------------------- datasets
def generate(cfg: GenerateCfg, out: str | Path, *, workers: int = 0, resume: bool = False,
             progress: bool = False, engine: EngineCfg | None = None) -> Dataset:
    """Simulate `cfg.n` grasp configurations into the dataset folder `out`.

    Args:
        cfg: The generation config (its seed included); see `GenerateCfg.from_preset`.
        out: Dataset folder to create (or, with `resume`, to continue).
        workers: Worker processes; 0: all cores (capped at the cores, with a note on stderr);
            1: everything in this process.
        resume: Continue an interrupted run made with the same settings.
        progress: Progress bar on stderr.
        engine: Local processes (default) or Ray tasks (`vistac.engine.EngineCfg`).

    Returns:
        The finished dataset.

    Raises:
        UserError: a missing ``--objects`` path, an unusable `out`, bad meshes (strict), no
            usable object.
    """
    from contextlib import nullcontext

    from vistac.dataset.files import check_out_dir
    from vistac.engine import EngineCfg, ForkServer, check_workers
    from vistac.fork_pool import spawn_problem
    from vistac_sim.generate import WORKER_MODULES
    from vistac_sim.generate.config import GenerateCfg

    cfg, out = config_arg(cfg, GenerateCfg, "cfg"), folder_arg(out, "out")
    workers = count_arg(workers, "workers")
    engine = optional_config_arg(engine, EngineCfg, "engine")
    for path in cfg.objects.paths:
        if not Path(path).exists():
            raise UserError(f"--objects {path}: no such file or folder")
    if cfg.render.textures is not None:
        from vistac_sim.render.materials import uses_textures
        from vistac_sim.render.textures import user_textures

        if not uses_textures(cfg):
            raise UserError(f"--textures {cfg.render.textures}: no effect uses textures (add "
                            "--preset photo, or a scene with object_material or table kinds)")
        user_textures(cfg.render.textures)  # a bad folder fails now, not in a worker
    workers = check_workers(workers)
    engine = engine or EngineCfg()
    out = check_out_dir(out)
    forks = engine.engine == "local" and workers > 1
    problem = spawn_problem() if forks else None
    if problem is not None:  # e.g. an embedded interpreter: the work is done here instead
        print(f"note: workers: {problem}; generating in this process", file=sys.stderr)
        workers, forks = 1, False
    # started first, the fork server's imports run beside this process's own, below
    with ForkServer(WORKER_MODULES) if forks else nullcontext() as server:
        from vistac_sim.generate.run import generate as run_generation

        # the run holds the folder's lock; it cleans up only what it made itself
        manifest = run_generation(cfg, out, workers=workers, resume=resume, progress=progress,
                                  engine=engine, server=server)
    return Dataset(out, already_complete=bool(manifest.get("already_complete")))


def open_dataset(path: str | Path) -> Dataset:
    """A complete dataset folder, checked (manifest, both tables, labels) on opening.

    Raises:
        UserError: not a dataset, an unfinished one, or malformed content (file, row, reason).
    """
    ds = Dataset(Path(path))
    ds.tables  # noqa: B018 (reads and checks it now, so that a bad folder fails here)
    return ds


def ingest(sources: IngestSources, out: str | Path, cfg: IngestCfg | None = None) -> Dataset:
    """Turn RH8D/FTS-3 recordings (or label spreadsheets) and their images into a dataset.

    Args:
        sources: Where the recordings, images and optional labels are, and the split.
        out: Dataset folder to create.
        cfg: Grasp detection and rejection criteria (default `IngestCfg()`).

    Raises:
        UserError: unreadable or inconsistent inputs, an unusable `out`.
    """
    from vistac.dataset.files import check_out_dir
    from vistac.dataset.ingest.config import IngestCfg, IngestSources
    from vistac.dataset.ingest.run import ingest as run_ingest

    sources, out = config_arg(sources, IngestSources, "sources"), folder_arg(out, "out")
    out = check_out_dir(out)
    run_ingest(sources, out, optional_config_arg(cfg, IngestCfg, "cfg") or IngestCfg())
    return Dataset(out)


# ------------------------------------------------------------------------------- learning
def train(cfg: TrainCfg, data: str | Path, out: str | Path, *, resume: bool = False,
          progress: bool = False) -> Run:
    """Train a model on dataset `data` into the run folder `out`.

    Args:
        cfg: The training settings (`TrainCfg()` is the default recipe,
            `TrainCfg.from_protocol("study")` the reference study's); its ``data`` and ``out``
            are replaced by the arguments.
        data: Dataset folder.
        out: Run folder to create (or, with `resume`, to continue).
        resume: Continue the run in `out` (same settings and dataset).
        progress: Progress bars and a line per epoch on stderr.

    Returns:
        The run, with its selected epoch and validation objective.

    Raises:
        UserError: an incomplete dataset, an unusable `out`, `--init` not a finished run,
            a diverged training (`TrainingDiverged`).
    """
    from vistac_learn.train.build import check_paths
    from vistac_learn.train.config import TrainCfg
    from vistac_learn.train.job import JobCfg, run_job

    cfg = config_arg(cfg, TrainCfg, "cfg")
    data, out = folder_arg(data, "data"), folder_arg(out, "out")
    cfg = dataclasses.replace(cfg, data=str(data), out=str(out))
    check_paths(cfg)
    res = run_job(JobCfg(cfg, resume="yes" if resume else "no", progress=progress))
    return Run(Path(res.run), res.best_epoch, res.objective)


def evaluate(target: Run | str | Path | EvaluateCfg, *, progress: bool = False,
             **options: Any) -> Evaluation:
    """Score a run (or a baseline) on a dataset split with the study's metrics.

    Args:
        target: A `Run`, a run folder, or a complete `EvaluateCfg` (e.g. the geometric
            baseline: ``EvaluateCfg(baseline="geometric", data=D, out=O)``).
        progress: Progress bars on stderr.
        **options: Fields of `EvaluateCfg` when `target` is a run: ``split`` ("test"),
            ``tta`` ("recipe": as the run's recipe says; "on"; "off"), ``checkpoint``,
            ``data``, ``out`` (default `EvaluateCfg.out_dir`: ``<run>/eval/<split>``, with
            ``-tta`` for ``tta="on"``, ``-no-tta`` for ``tta="off"``), ``no_plots``,
            ``device``, ``cross_dataset``, ``max_missing_pct``, ``no_references``.

    Returns:
        The score; ``.metrics`` is ``metrics.json``'s ``"metrics"``, ``.table`` the study's
        table.

    Raises:
        UserError: not a run folder, a dataset other than the run's (without
            ``cross_dataset``), an unusable output folder.
    """
    from vistac.dataset import read_manifest
    from vistac.dataset.files import check_out_dir
    from vistac_learn.evaluate.config import EvaluateCfg

    if isinstance(target, EvaluateCfg):
        if options:
            raise UserError("evaluate: give the options in the EvaluateCfg, not beside it")
        cfg = config_arg(target, EvaluateCfg, "target")
    else:
        if not isinstance(target, Run | str | os.PathLike):
            raise UserError(f"target: expected a Run, a run folder or an EvaluateCfg, got "
                            f"{brief(target)}")
        run = target.path if isinstance(target, Run) else folder_arg(target, "target")
        cfg = EvaluateCfg(run=str(run), **options)  # a ConfigError names the field
    if cfg.data is not None:
        try:
            read_manifest(Path(cfg.data))
        except UserError as exc:
            raise UserError(f"--data {exc}") from None
    out = check_out_dir(cfg.out_dir)
    with hold(out, "evaluate"):  # refuses a folder of another kind, or of a user's files
        res = _score(cfg, out, progress)
    return Evaluation(out, res)


def _score(cfg: EvaluateCfg, out: Path, progress: bool) -> dict:
    from vistac_learn.evaluate.run import evaluate_baseline, evaluate_run

    score = evaluate_baseline if cfg.baseline else evaluate_run
    return score(cfg, out, progress=progress)


def tune(base: TrainCfg, data: str | Path, out: str | Path, *, trials: int = 20,
         space: str | Path | None = None, seed: int = 0, resume: bool = False,
         engine: EngineCfg | None = None, trial: TrialCfg | None = None,
         progress: bool = False, on_start: Callable[[int], None] | None = None) -> Report:
    """Tune training options by Bayesian optimisation on the validation split.

    Args:
        base: The trials' settings apart from the tuned ones (the search space's).
        data: Dataset folder.
        out: Tuning folder to create (or, with `resume`, to continue).
        trials: Trials in total.
        space: YAML or JSON file changing the search space (default: log10 lr, log10 weight
            decay, batch size, crop jitter).
        seed: Seed of the optimiser.
        resume: Continue the tuning in `out`.
        engine: Local (default) or Ray tasks.
        trial: Resources of a trial on Ray (`TrialCfg`).
        progress: Progress bar on stderr.
        on_start: Called once the engine is up, with the number of trials run at once.

    Returns:
        The finished trials (rows of ``trials.csv``) and the best one.

    Raises:
        UserError: bad settings, a folder holding another tuning or held by another process,
            no trial that succeeded. (A tuned option that `base` also sets is simply tuned: the
            CLI refuses such an option, Python callers set `space` instead.)
    """
    from vistac.engine import EngineCfg, preflight
    from vistac_learn.train.build import check_data, check_paths
    from vistac_learn.train.config import TrainCfg
    from vistac_learn.tune.driver import TuneCfg, check_folder, no_success, run_tune_held
    from vistac_learn.tune.engines import TRIAL_OPTIONS, TrialCfg, tune_runner
    from vistac_learn.tune.space import load_space

    base = config_arg(base, TrainCfg, "base")
    data, out = folder_arg(data, "data"), folder_arg(out, "out")
    trials, seed = count_arg(trials, "trials"), count_arg(seed, "seed")
    space = None if space is None else folder_arg(space, "space")
    engine = optional_config_arg(engine, EngineCfg, "engine") or EngineCfg()
    trial = optional_config_arg(trial, TrialCfg, "trial") or TrialCfg()
    if engine.engine == "local":
        for name in TRIAL_OPTIONS:
            if getattr(trial, name) != getattr(TrialCfg(), name):
                raise UserError(f"--{name.replace('_', '-')}: needs --engine ray")
    search = load_space(space)
    base = dataclasses.replace(base, data=str(data), out=str(out))
    if engine.engine == "ray" and base.device == "cuda" and trial.trial_gpus == 0:
        raise UserError("--device cuda: with --engine ray a trial sees only the GPUs Ray gives "
                        "it; give each one with --trial-gpus (e.g. 1)")
    check_paths(base)
    try:
        cfg = TuneCfg(out=str(out), trials=trials, seed=seed)
    except UserError as exc:
        raise UserError(f"--{str(exc).replace('seed:', 'tune-seed:')}") from None
    with hold(out, "tune"):  # the folder's checks and the tuning under one lock
        check_folder(cfg, base, search, resume)
        _notes(check_data(base, progress=progress), progress)
        preflight(engine)
        with tune_runner(engine, base, trial, progress=progress) as runner:
            if on_start is not None:
                on_start(runner.concurrency)
            res = run_tune_held(cfg, base, search, resume=resume, runner=runner,
                                progress=progress)
        if res.best is None:
            raise UserError(f"--out {out}: no trial succeeded ({no_success(res.rows)}); nothing is "
                            "best (see trials.csv); narrow the space (e.g. lower lr bounds with "
                            "--space) or check the data")
    return Report(Path(out), res.rows, res.best)


def sim2real(cfg: Sim2RealCfg, base: TrainCfg, *, max_cells: int | None = None,
             progress: bool = False, runner: Any = None) -> Report:
    """Pretrain on simulation, fine-tune on fractions of real data (`Sim2RealCfg`).

    Args:
        cfg: The experiment (datasets, fractions, seeds, folder).
        base: The runs' training settings (each cell sets its seed, fraction, init and splits).
        max_cells: Stop after this many new cells (call again to continue).
        progress: Progress bar on stderr.
        runner: Runs the cells' training jobs (``run(jobs)`` yields (position, result); default
            `vistac_learn.train.job.LocalJobRunner`, e.g. one that also times each job).

    Returns:
        The trained cells (rows of ``cells.csv``); the report is ``cfg.out/report.md``.
    """
    from vistac.dataset.files import check_out_dir
    from vistac_learn.experiments import sim2real as S
    from vistac_learn.train.build import check_data
    from vistac_learn.train.config import TrainCfg

    cfg, base = config_arg(cfg, S.Sim2RealCfg, "cfg"), config_arg(base, TrainCfg, "base")
    S.check_inputs(cfg)
    cfg = S.resolved(cfg)
    check_out_dir(cfg.out)
    check_max_cells(max_cells)
    base = dataclasses.replace(base, data=cfg.real, out=str(Path(cfg.out) / "runs"))
    for run in (S.pretrain_cfg(cfg, base), base):
        _notes(check_data(run, progress), progress)
    rows = S.run_sim2real(cfg, base, max_cells=max_cells, progress=progress, runner=runner)
    return Report(Path(cfg.out), rows)


def label_noise(cfg: LabelNoiseCfg, base: TrainCfg, *, max_cells: int | None = None,
                progress: bool = False, runner: Any = None) -> Report:
    """Accuracy against the level of label noise (`LabelNoiseCfg`).

    Args:
        cfg: The experiment (dataset with clean forces, levels, seeds, folder).
        base: The runs' training settings (each cell sets its seed).
        max_cells: Stop after this many new cells (call again to continue).
        progress: Progress bar on stderr.
        runner: Runs the cells' training jobs (``run(jobs)`` yields (position, result); default
            `vistac_learn.train.job.LocalJobRunner`, e.g. one that also times each job).

    Returns:
        The trained cells (rows of ``cells.csv``); the report is ``cfg.out/report.md``.
    """
    from vistac.dataset.files import check_out_dir
    from vistac_learn.experiments import label_noise as L
    from vistac_learn.train.build import check_data
    from vistac_learn.train.config import TrainCfg

    cfg, base = config_arg(cfg, L.LabelNoiseCfg, "cfg"), config_arg(base, TrainCfg, "base")
    L.check_inputs(cfg)
    cfg = L.resolved(cfg)
    check_out_dir(cfg.out)
    check_max_cells(max_cells)
    base = dataclasses.replace(base, data=cfg.data, out=str(Path(cfg.out) / "runs"))
    _notes(check_data(base, progress), progress)
    rows = L.run_label_noise(cfg, base, max_cells=max_cells, progress=progress, runner=runner)
    return Report(Path(cfg.out), rows)


def _notes(lines: list[str], progress: bool) -> None:
    """Lines worth a user's eye (fingertips not found per split), on stderr with progress."""
    if progress:
        for line in lines:
            print(line, file=sys.stderr, flush=True)
