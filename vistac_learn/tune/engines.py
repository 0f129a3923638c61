"""Where the trials of `vistac tune` run: one after the other here, or as Ray tasks.

`tune_runner` opens the runner of an engine for the length of a tuning. With ``--engine ray``
each trial is one Ray task running `run_job` (``--trial-cpus``, default 1, and ``--trial-gpus``,
default 0, reserved by Ray; Ray re-runs a trial whose worker or node died, and the trial
continues from its last checkpoint). As many trials run at once as the cluster's CPUs and GPUs
hold, at most ``--max-concurrent``; the driver keeps the project's own optimiser
(suggest/register, see `vistac_learn.tune.driver`) and asks it for a new trial whenever one
finishes. Ray Tune's `BayesOptSearch` is not used: Ray 2.60's fails with bayesian-optimization
3.x (it calls the removed ``bayes_opt.UtilityFunction``).

The trials read ``--data`` and write their run folders under ``--out`` on the node that runs
them, so on a cluster both paths must be the same shared folder on every node (NFS, say): a
trial's run folder (checkpoints, metrics) is its state, which a retried or resumed trial
continues from, whichever node picks it up.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

from vistac.config import Config, param
from vistac.engine import ONLY_ASSIGNED_GPUS, EngineCfg, RayRunner, ray_session
from vistac_learn.train.build import build_view
from vistac_learn.train.config import TrainCfg

TRIAL_RETRIES = 2  # times Ray re-runs a trial whose worker or node died
TRIAL_OPTIONS = ("trial_cpus", "trial_gpus")


@dataclass(frozen=True)
class TrialCfg(Config):
    """What Ray reserves for each trial (``--engine ray``)."""

    trial_cpus: float = param(1.0, gt=0, le=4096, metavar="C", help="with --engine ray: CPUs "
                              "Ray reserves for each trial (trials at once: the cluster's CPUs "
                              "/ C, at most --max-concurrent)")
    trial_gpus: float = param(0.0, ge=0, le=64, metavar="G", help="with --engine ray: GPUs Ray "
                              "reserves for each trial, the only ones it sees (0: trials see "
                              "no GPU and train on CPU; 0.5: two trials share one)")


@contextmanager
def tune_runner(engine: EngineCfg, base: TrainCfg, trial: TrialCfg = TrialCfg(),
                progress: bool = False) -> Iterator[Any]:
    """The runner of the trials (``run(items)``, ``concurrency``), open for the block.

    With Ray the fingertip table of the dataset is located here first, once, so that trials
    running at once do not each locate it and race to write the cache.

    Raises:
        UserError: Ray missing, the cluster unreachable, bad data.
    """
    from vistac_learn.train.job import LocalJobRunner, run_job
    from vistac_learn.train.loop import TrainingDiverged

    if engine.engine == "local":
        yield LocalJobRunner(run_job, (TrainingDiverged,))
        return
    warm_fingertip_cache(base, progress)
    with ray_session(engine) as ray:
        yield RayRunner(ray, run_job, (TrainingDiverged,), max_concurrent=engine.max_concurrent,
                        num_cpus=trial.trial_cpus, num_gpus=trial.trial_gpus,
                        max_retries=TRIAL_RETRIES, runtime_env=ONLY_ASSIGNED_GPUS)


def warm_fingertip_cache(base: TrainCfg, progress: bool = False) -> None:
    """Locate the fingertips of ``base.data`` into its cache, if the trials' view needs them."""
    if not build_view(base).needs_tips:
        return
    from vistac.dataset import open_tables
    from vistac_learn.data.fingertip_table import fingertip_table

    fingertip_table(open_tables(base.data), cache_dir=base.cache_dir, progress=progress)
