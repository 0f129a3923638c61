"""`vistac tune`: Bayesian optimisation of `vistac train`'s options on the validation split."""

from __future__ import annotations

import argparse

from vistac.config import HelpFormatter, add_options, from_options
from vistac.engine import ENGINE_OPTIONS, EngineCfg
from vistac.errors import UserError
from vistac_learn.train.command import OPTIONS, options_cfg
from vistac_learn.train.config import PROTOCOLS, TrainCfg
from vistac_learn.tune.engines import TRIAL_OPTIONS, TrialCfg


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
    p.add_argument("--data", required=True, help="dataset directory")
    p.add_argument("--out", required=True, help="tuning folder to create (or continue)")
    p.add_argument("--trials", type=int, default=20, help="trials in total")
    p.add_argument("--space", default=None, help="YAML or JSON file changing the search space")
    p.add_argument("--tune-seed", type=int, default=0, help="seed of the optimiser")
    p.add_argument("--resume", action="store_true", help="continue the tuning in --out")
    add_options(p, EngineCfg, ENGINE_OPTIONS)
    add_options(p, TrialCfg, TRIAL_OPTIONS)
    p.add_argument("--protocol", default="default", choices=tuple(PROTOCOLS),
                   help="the trials' set of defaults (see `vistac train`)")
    add_options(p, TrainCfg, OPTIONS)
    p.set_defaults(**{o: None for o in OPTIONS})
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_handler)


def _handler(args: argparse.Namespace) -> int:
    from vistac.api import tune
    from vistac_learn.tune.space import load_space

    engine = from_options(EngineCfg, args, ENGINE_OPTIONS)
    trial = from_options(TrialCfg, args, TRIAL_OPTIONS)
    space = load_space(args.space)
    for d in space.dims:
        if getattr(args, d.name) is not None:
            flag = "--" + d.name.replace("_", "-")
            raise UserError(f"{flag}: tuned (in the search space); drop it, or take it out of "
                            "the space with --space")

    def started(k: int) -> None:
        if engine.engine == "ray" and not args.quiet:
            print(f"tune on Ray: {k} trial{'s' if k > 1 else ''} at once ({trial.trial_cpus:g} "
                  f"CPU, {trial.trial_gpus:g} GPU each)", flush=True)

    res = tune(options_cfg(args), args.data, args.out, trials=args.trials, space=args.space,
               seed=args.tune_seed, resume=args.resume, engine=engine, trial=trial,
               progress=not args.quiet, on_start=started)
    params = ", ".join(f"{d.name}={res.best[d.name]:.4g}" for d in space.dims)
    print(f"best of {len(res.rows)} trials: trial {res.best['trial']}, validation median "
          f"angle {res.best['objective']:.2f} deg ({params}); {args.out}/best.json")
    return 0
