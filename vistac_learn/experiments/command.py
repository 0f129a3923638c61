"""`vistac experiment {sim2real,label-noise}`: the options and the handlers.

Each experiment's own settings are declared by its config (`Sim2RealCfg`, `LabelNoiseCfg`);
every `vistac train` option that the experiment does not set per cell passes through to its
runs (e.g. ``--epochs``, ``--model``, ``--protocol``), as in `vistac tune`.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from pathlib import Path

from vistac.config import Config, ConfigError, apply, param
from vistac.config_options import (
    HelpFormatter,
    add_options,
    flag_labels,
    flag_of,
    from_options,
    option_values,
)
from vistac.dataset.files import check_out_dir
from vistac.errors import UserError
from vistac.progress import add_progress_option, progress_wanted
from vistac_learn.train.command import OPTIONS, add_train_options
from vistac_learn.train.config import TrainCfg, protocol_cfg

# what each cell sets itself, so not an option of the experiments
PER_CELL = ("seed", "train_fraction", "init", "freeze", "train_split", "val_split")
TRAIN_OPTIONS = tuple(o for o in OPTIONS if o not in PER_CELL)


@dataclass(frozen=True)
class ExperimentCommandCfg(Config):
    """The options of `vistac experiment` besides the experiment's config and the runs'."""

    max_cells: int | None = param(None, ge=1, help="stop after this many new cells (run again "
                                  "to continue)")


def add_command(sub: argparse._SubParsersAction) -> None:
    """Register `vistac experiment` and its experiments."""
    from vistac_learn.experiments.label_noise import LabelNoiseCfg
    from vistac_learn.experiments.sim2real import Sim2RealCfg

    p = sub.add_parser(
        "experiment", help="sim-to-real fine-tuning and label-noise experiments",
        description="Grids of training runs with a report folder (cells.csv, results.csv, "
        "report.md, a PNG). A killed experiment continues when the same command runs again "
        "(finished cells are skipped). `vistac experiment NAME --help` shows the options.",
        formatter_class=HelpFormatter)
    kinds = p.add_subparsers(dest="experiment", required=True, metavar="EXPERIMENT")
    s = kinds.add_parser(
        "sim2real", help="pretrain on simulation, fine-tune on fractions of real data",
        description="Per seed: a model trained on --sim (scored zero-shot on the real test "
        "split); per fraction of --real's training split and seed: one trained from scratch "
        "and the sim model fine-tuned (--init) on the same subset. All scored on --real's test "
        "split; mean +- std over seeds; the report states the domain gap.",
        formatter_class=HelpFormatter, allow_abbrev=False)
    add_options(s, Sim2RealCfg, ("sim", "real", "fractions", "seeds", "freeze", "sim_epochs",
                                 "sim_rotations", "sim_n_rotations"))
    _common(s, Sim2RealCfg)
    s.set_defaults(func=_sim2real)
    n = kinds.add_parser(
        "label-noise", help="accuracy against the level of label noise",
        description="Labels redrawn from --data's clean forces by the generator's noise model "
        "(--noise of `vistac generate`) at each level and seed, reproducibly, without "
        "simulating again; one model per level and seed, scored on the test split against the "
        "clean labels and the noisy cones.",
        formatter_class=HelpFormatter, allow_abbrev=False)
    add_options(n, LabelNoiseCfg, ("data", "levels", "seeds"))
    _common(n, LabelNoiseCfg)
    n.set_defaults(func=_label_noise)


def _common(p: argparse.ArgumentParser, cls: type) -> None:
    add_options(p, cls, ("out",))
    add_options(p, ExperimentCommandCfg, ("max_cells",))
    add_train_options(p, TRAIN_OPTIONS)
    add_progress_option(p)


def base_cfg(args: argparse.Namespace, data: str) -> TrainCfg:
    """The runs' training settings: the protocol's defaults, then the options given."""
    given = {k: v for k, v in option_values(args, TrainCfg, TRAIN_OPTIONS).items()
             if v is not None}
    base = protocol_cfg(args.protocol, data, str(Path(args.out) / "runs"))
    cfg = apply(base, given, labels=flag_labels(TrainCfg, TRAIN_OPTIONS))
    if cfg.cache_dir is not None:
        check_out_dir(cfg.cache_dir, "--cache-dir")
    return cfg


def make_cfg(cls: type, **values):
    """An experiment config, its errors naming the option."""
    try:
        return cls(**values)
    except ConfigError as exc:
        raise UserError(f"{flag_of(cls, exc.key)}: {exc.reason}") from None


def _sim2real(args: argparse.Namespace) -> int:
    from vistac.api import sim2real
    from vistac_learn.experiments.sim2real import Sim2RealCfg

    cfg = make_cfg(Sim2RealCfg, sim=args.sim, real=args.real, out=args.out,
                   fractions=tuple(args.fractions), seeds=args.seeds, freeze=args.freeze,
                   sim_epochs=args.sim_epochs, sim_rotations=args.sim_rotations,
                   sim_n_rotations=args.sim_n_rotations)
    res = sim2real(cfg, base_cfg(args, cfg.real), max_cells=_max_cells(args),
                   progress=progress_wanted(args))
    return _done(args.out, len(res.rows), cfg.seeds * (1 + 2 * len(cfg.fractions)))


def _label_noise(args: argparse.Namespace) -> int:
    from vistac.api import label_noise
    from vistac_learn.experiments.label_noise import LabelNoiseCfg

    cfg = make_cfg(LabelNoiseCfg, data=args.data, out=args.out, levels=tuple(args.levels),
                   seeds=args.seeds)
    res = label_noise(cfg, base_cfg(args, cfg.data), max_cells=_max_cells(args),
                      progress=progress_wanted(args))
    return _done(args.out, len(res.rows), len(cfg.levels) * cfg.seeds)


def _max_cells(args: argparse.Namespace) -> int | None:
    return from_options(ExperimentCommandCfg, args, ("max_cells",)).max_cells


def _done(out: str, n: int, total: int) -> int:
    state = "finished" if n == total else f"{n} of {total} cells done (run again to continue)"
    print(f"experiment {state}: {Path(out) / 'report.md'}")
    return 0

