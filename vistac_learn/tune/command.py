"""`vistac tune`: Bayesian optimisation of `vistac train`'s options on the validation split."""

from __future__ import annotations

import argparse
from dataclasses import dataclass

from vistac.config import Config, param
from vistac.config_options import HelpFormatter, add_options, from_options
from vistac.engine import ENGINE_OPTIONS, EngineCfg
from vistac.errors import UserError
from vistac.progress import add_progress_option, progress_wanted
from vistac_learn.train.command import TrainCommandCfg, add_train_options, options_cfg
from vistac_learn.tune.driver import TuneCfg
from vistac_learn.tune.engines import TRIAL_OPTIONS, TrialCfg

TUNE_OPTIONS = ("out", "trials")  # `seed` (--tune-seed) after --space


@dataclass(frozen=True)
class TuneCommandCfg(Config):
    """The options of `vistac tune` besides the tuning's (`TuneCfg`) and the trials' settings."""

    space: str | None = param(None, help="YAML or JSON file changing the search space")
    resume: bool = param(False, help="continue the tuning in --out")


def add_command(sub: argparse._SubParsersAction) -> None:
    """Register `vistac tune`."""
    p = sub.add_parser(
        "tune",
        help="tune training options by Bayesian optimisation",
        description="Bayesian optimisation (Gaussian process, the bayesian-optimization "
        "package) of training options; objective: the validation median angle to the cone "
        "mean (the test split is never used). Default space: log10 lr, log10 weight decay, "
        "batch size, crop jitter; --space FILE changes it. Every `vistac train` option passes "
        "through to the trials. Writes OUT/trials.csv, best.json, convergence.png and one run "
        "folder per trial; --resume continues after a kill. --engine ray runs the trials as "
        "Ray tasks, as many at once as the cluster's CPUs and GPUs hold (--trial-cpus, "
        "--trial-gpus; at most --max-concurrent); on a cluster --data and --out must be on a "
        "filesystem every node shares.",
        formatter_class=HelpFormatter,
    )
    add_options(p, TrainCommandCfg, ("data",))
    add_options(p, TuneCfg, TUNE_OPTIONS)
    add_options(p, TuneCommandCfg, ("space",))
    add_options(p, TuneCfg, ("seed",))
    add_options(p, TuneCommandCfg, ("resume",))
    add_options(p, EngineCfg, ENGINE_OPTIONS)
    add_options(p, TrialCfg, TRIAL_OPTIONS)
    add_train_options(p)
    add_progress_option(p)
    p.set_defaults(func=_handler)


def _handler(args: argparse.Namespace) -> int:
    from vistac.api import tune
    from vistac_learn.tune.space import load_space

    engine = from_options(EngineCfg, args, ENGINE_OPTIONS)
    trial = from_options(TrialCfg, args, TRIAL_OPTIONS)
    tuning = from_options(TuneCfg, args, (*TUNE_OPTIONS, "seed"))
    cmd = from_options(TuneCommandCfg, args, ("space", "resume"))
    progress = progress_wanted(args)
    space = load_space(cmd.space)
    for d in space.dims:
        if getattr(args, d.name) is not None:
            flag = "--" + d.name.replace("_", "-")
            raise UserError(f"{flag}: tuned (in the search space); drop it, or take it out of "
                            "the space with --space")

    def started(k: int) -> None:
        if engine.engine == "ray" and progress:
            print(f"tune on Ray: {k} trial{'s' if k > 1 else ''} at once ({trial.trial_cpus:g} "
                  f"CPU, {trial.trial_gpus:g} GPU each)", flush=True)

    res = tune(options_cfg(args), args.data, tuning.out, trials=tuning.trials, space=cmd.space,
               seed=tuning.seed, resume=cmd.resume, engine=engine, trial=trial,
               progress=progress, on_start=started)
    params = ", ".join(f"{d.name}={res.best[d.name]:.4g}" for d in space.dims)
    print(f"best of {len(res.rows)} trials: trial {res.best['trial']}, validation median "
          f"angle {res.best['objective']:.2f} deg ({params}); {tuning.out}/best.json")
    return 0
