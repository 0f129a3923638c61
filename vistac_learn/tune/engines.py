"""Where the trials of `vistac tune` run: one after the other here, or as Ray tasks.

`tune_runner` opens the runner of an engine for the length of a tuning. With ``--engine ray``
each trial is one Ray task running `run_job` (one CPU; Ray re-runs a trial whose worker or node
died, and the trial continues from its last checkpoint). As many trials run at once as the
cluster has CPUs for, at most ``--max-concurrent``; the driver keeps the project's own optimiser
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
from typing import Any

from vistac.engine import EngineCfg, RayRunner, ray_session
from vistac_learn.train.config import TrainCfg, build_view
from vistac_learn.train.job import LocalRunner, run_job
from vistac_learn.train.loop import TrainingDiverged

TRIAL_CPUS = 1  # CPUs Ray reserves for each trial
TRIAL_RETRIES = 2  # times Ray re-runs a trial whose worker or node died


@contextmanager
def tune_runner(engine: EngineCfg, base: TrainCfg) -> Iterator[Any]:
    """The runner of the trials (``run(items)``, ``concurrency``), open for the block.

    With Ray the fingertip table of the dataset is located here first, once, so that trials
    running at once do not each locate it and race to write the cache.

    Raises:
        UserError: Ray missing, the cluster unreachable, bad data.
    """
    if engine.engine == "local":
        yield LocalRunner(run_job, (TrainingDiverged,))
        return
    warm_fingertip_cache(base)
    with ray_session(engine) as ray:
        yield RayRunner(ray, run_job, (TrainingDiverged,), max_concurrent=engine.max_concurrent,
                        num_cpus=TRIAL_CPUS, max_retries=TRIAL_RETRIES)


def warm_fingertip_cache(base: TrainCfg) -> None:
    """Locate the fingertips of ``base.data`` into its cache, if the trials' view needs them."""
    if not build_view(base).needs_tips:
        return
    from vistac.dataset import open_dataset
    from vistac_learn.data.fingertips import fingertip_table

    fingertip_table(open_dataset(base.data), cache_dir=base.cache_dir)
