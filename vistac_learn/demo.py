"""`vistac demo`: the main job end to end on a small default, with a report.

Generates a small simulated dataset (objects split between train, validation and test), trains
the default model (`pinchnet` on the pinch view: contact geometry read from the fingertip
crops, both fingers), evaluates it and the geometric baseline on the held-out objects, beside
the references of simulated data (the noise floor and the pinch baseline,
`vistac_learn.evaluate.references`), and writes `report.md` with the study-layout tables and
figures. Re-running reuses what is already done (the dataset, a finished or interrupted
training run).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import shutil
import time
from dataclasses import dataclass
from pathlib import Path

from vistac.config import Config, ConfigError, param
from vistac.config_options import RawDescriptionHelpFormatter, add_options, from_options
from vistac.dataset import SplitCfg
from vistac.progress import add_progress_option, progress_wanted


@dataclass(frozen=True)
class DemoCfg(Config):
    """The demo's small default: dataset size, training length, model and seed."""

    out: Path = param(Path("runs/demo"), help="demo folder")
    n: int = param(600, ge=30, le=1_000_000, help="configurations to simulate")
    epochs: int = param(15, ge=1, le=10_000, help="training epochs")
    model: str = param("pinchnet", help="registered model (`vistac models`)")
    workers: int = param(0, ge=0, help="generate processes (0: all cores)")
    seed: int = param(0, ge=0, lt=2**32, help="seed of the dataset and of the run")

    def __post_init__(self) -> None:
        super().__post_init__()
        from vistac_learn.train.config import _is_model

        if not _is_model(self.model):
            raise ConfigError("model", f"unknown model {self.model!r} (see `vistac models`)")


def run_demo(cfg: DemoCfg, progress: bool = True) -> Path:
    """Run the demo pipeline into `cfg.out` and return the path of its report.

    Each step is a call of the Python API (`vistac.api`), as a script of one's own would make it;
    `progress`: their progress on stderr.
    """
    from vistac import api
    from vistac_learn.evaluate.config import EvaluateCfg
    from vistac_learn.train.config import TrainCfg
    from vistac_sim.generate.config import GenerateCfg

    out = cfg.out
    out.mkdir(parents=True, exist_ok=True)
    data, run = out / "data", out / "run"
    t0 = time.perf_counter()
    if not (data / "manifest.json").exists():
        gen = GenerateCfg.from_preset("clean", noise=0.05, n=cfg.n, seed=cfg.seed,
                                      split=SplitCfg(by="object"))
        api.generate(gen, data, workers=cfg.workers, resume=(data / ".partial").exists(),
                     progress=progress)
    t_data = time.perf_counter() - t0
    t1 = time.perf_counter()
    train = TrainCfg.from_protocol("default", model=cfg.model, epochs=cfg.epochs, seed=cfg.seed)
    trained = api.train(train, data, run,
                        resume=(run / "checkpoints" / "last.pt").exists(), progress=progress)
    t_train = time.perf_counter() - t1
    api.evaluate(trained, progress=progress)
    api.evaluate(EvaluateCfg(baseline="geometric", data=str(data), out=str(out / "baseline"),
                             finger="both", rotations="none"), progress=progress)
    return write_report(out, data, run, t_data, t_train)


def write_report(out: Path, data: Path, run: Path, t_data: float, t_train: float) -> Path:
    """Write `report.md` from the dataset manifest and the two metrics files."""
    from vistac_learn.evaluate.references import reference_entries
    from vistac_learn.metrics.scoring import format_table

    manifest = json.loads((data / "manifest.json").read_text())
    model = json.loads((run / "eval" / "test" / "metrics.json").read_text())
    base = json.loads((out / "baseline" / "metrics.json").read_text())
    figures = out / "figures"
    figures.mkdir(exist_ok=True)
    for src, name in [(run / "eval" / "test" / "cones_index.png", "model_cones_index.png"),
                      (run / "eval" / "test" / "cones_thumb.png", "model_cones_thumb.png"),
                      (run / "eval" / "test" / "error_hist_index.png", "model_error_hist.png"),
                      (out / "baseline" / "cones_index.png", "baseline_cones_index.png")]:
        if src.exists():
            shutil.copyfile(src, figures / name)
    first = sorted((data / "images").iterdir())[0]
    shutil.copyfile(first, figures / "example_input.png")
    counts = manifest["counts"]
    fingers = tuple(model["fingers"])
    refs = model.get("references")
    rows = [(f"{r['label']} ({f})", r["metrics"][f]) for r in (model, base) for f in fingers
            if f in r["metrics"]]
    about_refs = [] if not refs else [
        "The noise floor scores the dataset's noise-free forces as a prediction against the "
        "noisy presses: what the labels' own noise costs. The pinch baseline reads the contact "
        "points from the image and predicts the closing axis through them, clamped to the "
        f"friction cone (mu {refs['pinch']['friction']:g}), with no learning; "
        f"{refs['pinch']['ms_per_image']:.0f} ms per image, unrotated images.",
        ""]
    lines = [
        "# vistac demo report",
        "",
        f"Dataset `{data}`: {counts['configs']} configurations, {counts['presses']} presses, "
        f"split {counts['split']}, {counts['objects']} objects; noise "
        f"{manifest['config']['effects']['noise']}; "
        + (f"generated in {t_data:.1f} s." if t_data > 0.5 else "reused from an earlier run."),
        "",
        f"Model `{model['model']}` on `{model['variant']}` images, best epoch {model['epoch']} "
        f"(chosen on validation), trained in {t_train:.1f} s; inference "
        f"{model['images_per_s']:.0f} images/s on {model['device']}.",
        "",
        "## Test split: held-out objects, both fingers (the study's columns)",
        "",
        "```",
        format_table(rows + reference_entries(refs, fingers)),
        "```",
        "",
        *about_refs,
        "![example input](figures/example_input.png)",
        "![model cones, index](figures/model_cones_index.png)",
        "![model cones, thumb](figures/model_cones_thumb.png)",
        "![model error histogram](figures/model_error_hist.png)",
        "![baseline cones](figures/baseline_cones_index.png)",
        "",
    ]
    report = out / "report.md"
    report.write_text("\n".join(lines))
    return report


def add_command(sub: argparse._SubParsersAction) -> None:
    """Register `vistac demo`."""
    p = sub.add_parser(
        "demo", help="generate, train, evaluate and report on a small default",
        description=__doc__, formatter_class=RawDescriptionHelpFormatter)
    add_options(p, DemoCfg, OPTIONS)
    add_progress_option(p)
    p.set_defaults(func=_handler)


OPTIONS = tuple(f.name for f in dataclasses.fields(DemoCfg))


def _handler(args: argparse.Namespace) -> int:
    from vistac.dataset.files import check_out_dir
    from vistac.engine import check_workers

    cfg = from_options(DemoCfg, args, OPTIONS)
    check_out_dir(cfg.out)
    check_workers(cfg.workers)
    print(f"report: {run_demo(cfg, progress=progress_wanted(args))}")
    return 0
