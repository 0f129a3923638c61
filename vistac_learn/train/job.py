"""One training job: train a run, score it, return its numbers (`run_job`).

`vistac train`, `vistac tune` and the experiments all run their training through `run_job`, a
plain top-level function of one picklable config (`JobCfg`), so that a runner can execute jobs
in this process (`LocalJobRunner`) or as Ray tasks (`vistac.engine.RayRunner`): the runners of
`vistac.engine`, one interface (``runner.run(items)`` yields ``(position, result)`` as jobs
finish; ``runner.concurrency``).

The objective of a job is the validation median angle to the cone mean (degrees, averaged over
the run's fingers) at the epoch the run selected: the test split never enters it.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from vistac import engine
from vistac.config import Config, param
from vistac.dataset import SPLITS
from vistac.errors import UserError
from vistac_learn.data.samples import fingers_of
from vistac_learn.train.checkpoints import BEST_KEYS, RESTART, load_checkpoint
from vistac_learn.train.config import TrainCfg
from vistac_learn.train.loop import TrainingDiverged, train_run_folder
from vistac_learn.train.run_files import read_metrics
from vistac_learn.train.run_folder import damage

OBJECTIVE = "angle_to_mean_median_deg"
RESUME = ("no", "yes", "auto")


@dataclass(frozen=True)
class ScoreCfg(Config):
    """A split to score the job's best weights on after training."""

    name: str = param(help="name of the score (folder eval/<name> of the run)")
    split: str = param("test", choices=SPLITS, help="split to score")
    data: str | None = param(None, help="dataset to score on (default: the run's own; "
                             "another one is scored across datasets)")


@dataclass(frozen=True)
class JobCfg(Config):
    """A training job: the run's settings, what to score afterwards, how to start."""

    train: TrainCfg = param(help="the run")
    scores: tuple[ScoreCfg, ...] = param((), help="scores of the best weights after training")
    resume: str = param("auto", choices=RESUME, help="no: refuse a started run; yes: continue "
                        "one (it must exist); auto: continue a started run, else start")
    progress: bool = param(False, help="show progress bars")


@dataclass(frozen=True)
class JobResult:
    """What a finished job measured.

    Attributes:
        run: The run folder.
        objective: Validation median angle to the cone mean (deg, mean over fingers) at the
            selected epoch.
        best_epoch: The selected epoch (1-based).
        epochs: Epochs trained.
        first_train_loss: Training loss of the first epoch.
        val: The selected epoch's validation row (``val_<finger>_<metric>`` -> value).
        scores: Score name -> finger -> scalar metrics (see `ScoreCfg`).
        seconds: Wall time of the job.
    """

    run: str
    objective: float
    best_epoch: int
    epochs: int
    first_train_loss: float
    val: dict[str, float] = field(default_factory=dict)
    scores: dict[str, dict[str, dict[str, float]]] = field(default_factory=dict)
    seconds: float = 0.0

    def score(self, name: str, metric: str = OBJECTIVE) -> float:
        """A score's metric averaged over the fingers."""
        per = self.scores[name]
        return float(sum(m[metric] for m in per.values()) / len(per))


def run_job(cfg: JobCfg) -> JobResult:
    """Train (or continue) the job's run, score it, return its numbers.

    Raises:
        TrainingDiverged: the loss became non-finite (a `UserError`).
        UserError: bad settings or data.
    """
    from vistac_learn.evaluate.config import EvaluateCfg
    from vistac_learn.evaluate.run import evaluate_run

    t0 = time.perf_counter()
    out = Path(cfg.train.out)
    started = (out / "config.json").exists()
    resume = cfg.resume == "yes" or (cfg.resume == "auto" and started and not damage(out))
    train_run_folder(cfg.train, resume=resume, progress=cfg.progress)
    rows = read_metrics(out / "metrics.csv", RESTART)
    best = load_checkpoint(out / "checkpoints" / "best.pt", BEST_KEYS, RESTART)["epoch"]
    row = next((r for r in rows if int(r["epoch"]) == best), None)
    if row is None:
        raise UserError(f"{out / 'metrics.csv'}: no row of epoch {best}, the best checkpoint's; "
                        f"{RESTART}")
    fingers = fingers_of(cfg.train.finger)
    objective = sum(row[f"val_{f}_{OBJECTIVE}"] for f in fingers) / len(fingers)
    scores = {}
    for s in cfg.scores:
        res = evaluate_run(EvaluateCfg(run=str(out), data=s.data, split=s.split, no_plots=True,
                                       cross_dataset=s.data is not None,
                                       max_missing_pct=cfg.train.max_missing_pct),
                           out / "eval" / s.name)
        scores[s.name] = res["metrics"]
    return JobResult(str(out), float(objective), int(best), len(rows),
                     float(rows[0]["train_loss"]),
                     {k: v for k, v in row.items() if k.startswith("val_")}, scores,
                     time.perf_counter() - t0)


class LocalJobRunner(engine.LocalRunner):
    """Runs training jobs one after the other in this process (`vistac.engine.LocalRunner`,
    whose interface `vistac.engine.RayRunner` shares), by default `run_job` with a diverged
    loss as its result."""

    def __init__(self, job: Callable[[Any], Any] = run_job,
                 returned_errors: tuple[type[BaseException], ...] = (TrainingDiverged,)):
        super().__init__(job, returned_errors)
