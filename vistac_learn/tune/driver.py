"""Bayesian optimisation of training options (`vistac tune`): `run_tune`.

A Gaussian process (`bayes_opt`, suggest/register) proposes options; each trial is one training
job (`vistac_learn.train.job.run_job`) on the base run's settings with the proposed options,
scored by its validation median angle (lower is better; the optimiser maximises its negative).
The test split is never used.

Tuning folder (``--out T``):

- ``config.json``: the tuning settings, the base run's full config and the search space.
- ``trials.csv``: one row per finished trial (trial, options, objective, status, best epoch,
  seconds, run folder), rewritten atomically after every trial; a row never changes once written.
- ``pending.json``: trials suggested but not finished, with their options.
- ``best.json``, ``convergence.png``: the best trial so far, best objective against trial.
- ``trials/NNNN/``: each trial's run folder.

A tuning whose every trial failed (diverged) has no best trial: `vistac tune` then exits with
an error, and a plain rerun into the folder starts it over (`failed`). A damaged
``trials.csv`` or ``pending.json`` is not an error on ``--resume``: both are dropped and every
trial replayed from its run folder (the same suggestions, the runs continue where they are).

Repeatability and resume: the suggestion for trial i is computed by a fresh optimiser seeded
from (seed, i) that is given the finished trials in trial order, so it depends only on them; a
tuning killed at any point and resumed (``--resume``) replays the finished rows into the
optimiser, redoes the pending trials with their recorded options (continuing their run folders
where they had checkpoints) and then suggests what an uninterrupted tuning would have. With a
runner running several trials at once (`runner.concurrency` > 1) the trials in flight enter the
optimiser as "constant liars" (the worst objective so far), so that each suggestion differs.
"""

from __future__ import annotations

import csv
import dataclasses
import io
import json
import math
import os
import shutil
import warnings
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from vistac.config import Config, param, to_dict
from vistac.dataset.files import atomic_write_bytes, atomic_write_json
from vistac.errors import UserError
from vistac.folder_lock import hold
from vistac.progress import bar as progress_bar
from vistac_learn.train.config import TrainCfg
from vistac_learn.train.job import JobCfg, JobResult, LocalJobRunner
from vistac_learn.train.loop import TrainingDiverged
from vistac_learn.tune.space import SpaceCfg

FIXED_COLUMNS = ("trial", "objective", "status", "best_epoch", "seconds", "run")


@dataclass(frozen=True)
class TuneCfg(Config):
    """A tuning's own settings (the trained runs' come from the base `TrainCfg`)."""

    out: str = param(help="tuning folder")
    trials: int = param(20, ge=1, le=100_000, help="trials in total (a resumed tuning may "
                        "raise it)")
    seed: int = param(0, ge=0, lt=2**32, flag="--tune-seed",
                      help="seed of the optimiser's suggestions")


@dataclass(frozen=True)
class TuneResult:
    """The finished trials (rows of trials.csv) and the best one."""

    rows: list[dict[str, Any]]
    best: dict[str, Any] | None


def suggest(space: SpaceCfg, finished: list[dict], running: list[dict], trial: int,
            seed: int) -> dict[str, float | int]:
    """Training options for trial `trial`.

    Args:
        space: The search space.
        finished: Rows of finished trials (options and objective; NaN for a diverged trial).
        running: Options of trials in flight (not finished).
        trial: Index of the trial to suggest (0-based).
        seed: The tuning's seed.

    Returns:
        Option name -> value.
    """
    from bayes_opt import BayesianOptimization

    state = np.random.RandomState(np.random.SeedSequence([seed, trial]).generate_state(1)[0])
    with warnings.catch_warnings():  # integer parameters are "experimental" in bayes_opt 3
        warnings.simplefilter("ignore", UserWarning)
        opt = BayesianOptimization(f=None, pbounds=space.pbounds(), random_state=state,
                                   verbose=0, allow_duplicate_points=True)
    ok = [r["objective"] for r in finished if math.isfinite(r["objective"])]
    if trial < space.init_points or not ok:
        return space.values(opt.suggest())  # an empty optimiser suggests a random point
    worst = max(ok)
    for r in sorted(finished, key=lambda r: r["trial"]):
        target = r["objective"] if math.isfinite(r["objective"]) else worst
        opt.register(params=space.coords(r), target=-target)
    for values in running:  # constant liar: a trial in flight counts as the worst so far
        opt.register(params=space.coords(values), target=-worst)
    return space.values(opt.suggest())


def _read_rows(path: Path, space: SpaceCfg) -> list[dict[str, Any]]:
    """The rows of ``trials.csv``, one per trial (a trial written twice counts once).

    Raises:
        UserError: a damaged file (what to do in the message).
    """
    if not path.exists():
        return []
    types = {d.name: (int if d.type == "int" else float) for d in space.dims}
    rows: dict[int, dict[str, Any]] = {}
    try:
        with path.open(newline="") as fh:
            for r in csv.DictReader(fh):
                row = {k: types[k](r[k]) for k in types}
                row |= {"trial": int(r["trial"]), "objective": float(r["objective"]),
                        "status": str(r["status"]), "best_epoch": int(r["best_epoch"]),
                        "seconds": float(r["seconds"]), "run": str(r["run"])}
                rows.setdefault(row["trial"], row)
    except (OSError, UnicodeDecodeError, csv.Error, KeyError, TypeError, ValueError) as exc:
        raise UserError(f"{path}: damaged ({type(exc).__name__}: {exc})") from None
    return [rows[t] for t in sorted(rows)]


def _read_pending(path: Path) -> dict[int, dict]:
    """Trials suggested and not finished (``pending.json``): trial -> options.

    Raises:
        UserError: a damaged file.
    """
    if not path.exists():
        return {}
    try:
        data = json.loads(path.read_bytes())
        return {int(k): dict(v) for k, v in data.items()}
    except (OSError, UnicodeDecodeError, AttributeError, TypeError, ValueError) as exc:
        raise UserError(f"{path}: damaged ({type(exc).__name__})") from None


def no_success(rows: list[dict[str, Any]]) -> str:
    """Why no trial is best: ``N trials, all diverged`` or the statuses counted."""
    statuses = sorted({r["status"] for r in rows})
    if not rows:
        return "no trial ran"
    if len(statuses) == 1:
        return f"{len(rows)} trial{'s' if len(rows) > 1 else ''}, all {statuses[0]}"
    return ", ".join(f"{sum(r['status'] == s for r in rows)} {s}" for s in statuses)


def _write_rows(path: Path, rows: list[dict[str, Any]], space: SpaceCfg) -> None:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=[FIXED_COLUMNS[0], *(d.name for d in space.dims),
                                        *FIXED_COLUMNS[1:]], lineterminator="\n")
    w.writeheader()
    w.writerows(sorted(rows, key=lambda r: r["trial"]))
    atomic_write_bytes(path, buf.getvalue().encode())


def _meta(cfg: TuneCfg, base: TrainCfg, space: SpaceCfg) -> dict[str, Any]:
    return {"tune": to_dict(cfg), "base": _absolute(to_dict(base)), "space": space.to_json()}


_PATHS = ("data", "out", "cache_dir")
"""The base settings that are paths."""


def _absolute(base: dict[str, Any]) -> dict[str, Any]:
    """A tuning's base settings with its paths absolute (a relative one, recorded by an older
    version, as seen from here): resumed from another working directory, a tuning of the same
    dataset has the same settings."""
    return {k: os.path.abspath(v) if k in _PATHS and isinstance(v, str) else v
            for k, v in base.items()}


def check_folder(cfg: TuneCfg, base: TrainCfg, space: SpaceCfg, resume: bool) -> None:
    """Whether ``cfg.out`` can take this tuning (`run_tune` checks it too; a caller that starts
    an engine first checks before).

    Raises:
        UserError: a folder holding another tuning or other files, a resume without a tuning
            or with other settings.
    """
    _check_folder(cfg, _meta(cfg, base, space), resume)


TUNING_FILES = ("config.json", "trials.csv", "pending.json", "best.json", "convergence.png")


def failed(out: Path) -> bool:
    """Whether `out` holds a tuning whose every finished trial failed (none is best)."""
    if (out / "best.json").exists() or not (out / "config.json").exists():
        return False
    try:
        with (out / "trials.csv").open(newline="") as fh:
            statuses = [r["status"] for r in csv.DictReader(fh)]
    except (OSError, UnicodeDecodeError, csv.Error, KeyError):
        return False
    return bool(statuses) and "ok" not in statuses


def _start_over(out: Path) -> None:
    """Remove a failed tuning's files and trial folders (`failed`)."""
    for name in TUNING_FILES:
        (out / name).unlink(missing_ok=True)
    shutil.rmtree(out / "trials", ignore_errors=True)


def _check_folder(cfg: TuneCfg, meta: dict, resume: bool) -> None:
    out = Path(cfg.out)
    path = out / "config.json"
    if not resume:
        if failed(out):
            return  # a tuning without a successful trial: a rerun starts it over
        if path.exists():
            raise UserError(f"--out {out}: already holds a tuning; pass --resume or choose "
                            "another --out")
        if out.exists() and any(out.iterdir()):
            raise UserError(f"--out {out}: a folder that is not empty; choose another")
        return
    if not path.exists():
        raise UserError(f"--out {out}: no tuning to resume (no config.json); drop --resume")
    try:
        saved = json.loads(path.read_bytes())
        if not all(isinstance(saved.get(k), dict) for k in ("base", "space", "tune")):
            raise ValueError("not a tuning's settings")
    except (OSError, UnicodeDecodeError, AttributeError, ValueError):
        return  # damaged: written again from these options (each trial's run checks its own)
    saved["base"] = _absolute(saved["base"])
    for part in ("base", "space"):
        if saved[part] != meta[part]:
            diff = [k for k in meta[part] if saved[part].get(k) != meta[part][k]]
            raise UserError(f"{path}: --resume with other {part} settings "
                            f"({', '.join(diff) or part})")
    if saved["tune"].get("seed") != cfg.seed:
        raise UserError(f"{path}: --resume with another --tune-seed ({saved['tune']['seed']})")


def run_tune(cfg: TuneCfg, base: TrainCfg, space: SpaceCfg, resume: bool = False,
             runner: Any = None, progress: bool = True) -> TuneResult:
    """Tune `base`'s options over `space` for ``cfg.trials`` trials (or continue a tuning).

    Args:
        cfg: The tuning's settings.
        base: The trials' run settings before the suggested options (its ``out`` is replaced
            by the trial's folder).
        space: The search space.
        resume: Continue the tuning in ``cfg.out``.
        runner: Runs job configs (``run(items)`` yields (position, result) as jobs finish;
            ``concurrency`` jobs at once); default `LocalJobRunner`, one at a time here.
        progress: Show a progress bar of trials.

    Returns:
        The finished trials and the best.

    Raises:
        UserError: a folder that holds another tuning, a resume with other settings, bad data,
            a folder that another process holds.
    """
    with hold(cfg.out, "tune"):
        return run_tune_held(cfg, base, space, resume, runner, progress)


def run_tune_held(cfg: TuneCfg, base: TrainCfg, space: SpaceCfg, resume: bool = False,
                  runner: Any = None, progress: bool = True) -> TuneResult:
    """`run_tune` for a caller that holds ``cfg.out``'s lock already (`vistac.folder_lock`)."""
    from vistac_learn.tune.plots import plot_convergence

    runner = runner or LocalJobRunner()
    out = Path(cfg.out)
    meta = _meta(cfg, base, space)
    _check_folder(cfg, meta, resume)
    if not resume and failed(out):
        _start_over(out)
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_json(out / "config.json", meta)
    rows_path, pending_path = out / "trials.csv", out / "pending.json"
    try:
        rows, pending = _read_rows(rows_path, space), _read_pending(pending_path)
    except UserError:  # damaged: every trial is replayed from its run folder (same suggestions,
        rows, pending = [], {}  # the runs continue where they are), as recorded before
    done = {r["trial"] for r in rows}
    pending = {k: v for k, v in pending.items() if k not in done}
    issued: list[int] = []

    def job_cfg(trial: int, values: dict) -> JobCfg:
        run = dataclasses.replace(base, out=str(out / "trials" / f"{trial:04d}"), **values)
        return JobCfg(run, resume="auto")

    def items() -> Iterator[JobCfg]:
        for trial in sorted(pending):  # redo what a kill interrupted, with its options
            issued.append(trial)
            yield job_cfg(trial, pending[trial])
        nxt = max([*done, *pending, -1]) + 1
        while nxt < cfg.trials:
            running = [pending[t] for t in pending]
            values = suggest(space, rows, running, nxt, cfg.seed)
            pending[nxt] = values
            atomic_write_json(pending_path, {str(k): v for k, v in sorted(pending.items())})
            issued.append(nxt)
            yield job_cfg(nxt, values)
            nxt += 1

    bar = progress_bar(total=max(cfg.trials, len(rows)), initial=len(rows), desc="tune",
                       unit="trial", enabled=progress, lines="each")
    best = _best(rows)
    _write_outputs(out, rows, best, space, base, plot_convergence)
    for position, result in runner.run(items()):
        trial = issued[position]
        if trial not in done:  # recorded once, whatever was recorded before a kill
            rows.append(_row(trial, pending[trial], result))
            done.add(trial)
            _write_rows(rows_path, rows, space)
        del pending[trial]
        atomic_write_json(pending_path, {str(k): v for k, v in sorted(pending.items())})
        best = _best(rows)
        _write_outputs(out, rows, best, space, base, plot_convergence)
        bar.update(1)
        if best is not None:
            bar.set_postfix(best=f"{best['objective']:.3g} deg (trial {best['trial']})")
    bar.close()
    return TuneResult(rows, best)


def _row(trial: int, values: dict, result: JobResult | BaseException) -> dict[str, Any]:
    row = {"trial": trial, **values}
    if isinstance(result, TrainingDiverged):
        return row | {"objective": math.nan, "status": "diverged", "best_epoch": 0,
                      "seconds": 0.0, "run": ""}
    return row | {"objective": result.objective, "status": "ok",
                  "best_epoch": result.best_epoch, "seconds": result.seconds,
                  "run": str(Path(result.run).name)}


def _best(rows: list[dict]) -> dict | None:
    ok = [r for r in rows if math.isfinite(r["objective"])]
    return min(ok, key=lambda r: (r["objective"], r["trial"])) if ok else None


def _write_outputs(out: Path, rows, best, space: SpaceCfg, base: TrainCfg, plot) -> None:
    if best is not None:
        values = {d.name: best[d.name] for d in space.dims}
        atomic_write_json(out / "best.json", {
            "trial": best["trial"], "objective": best["objective"],
            "objective_name": "validation median angle to the cone mean (deg)",
            "params": values, "best_epoch": best["best_epoch"],
            "run": str(out / "trials" / best["run"]), "n_trials": len(rows),
            "train": to_dict(dataclasses.replace(base, out=str(out / "trials" / best["run"]),
                                                 **values))})
    if rows:
        plot(sorted(rows, key=lambda r: r["trial"]), out / "convergence.png")
