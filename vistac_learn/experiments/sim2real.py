"""`vistac experiment sim2real`: does pretraining on simulated data save real data?

Per seed, one model is trained on the simulated dataset (``sim-only``; scored on the real test
split as it is: the zero-shot row). Per fraction of the real training split and seed, a model is
trained from scratch on that fraction (``scratch``) and the sim model is fine-tuned on the same
fraction (``finetune``, `TrainCfg.init`; the same seed draws the same subset, see
`subset_rows`). The sim-only runs may train for other epochs and rotations than the real ones
(``--sim-epochs``, ``--sim-rotations``, ``--sim-n-rotations``): a large simulated dataset
with one random rotation per sample and epoch, a study-sized real one with the study's 20 fixed
rotations. Every model is selected on the validation split of the dataset it trains on
and scored on the real test split, which never enters training or selection.

Outputs in ``--out``: ``cells.csv`` (one row per trained model), ``results.csv`` (mean and std
over seeds per arm and fraction), ``report.md`` (the table, the domain gap and the finding),
``sim2real.png`` (real test median angle against the fraction, mean +- std error bars), the
run folders under ``runs/``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from vistac.config import Config, ConfigError, param
from vistac.errors import UserError
from vistac.folder_lock import hold
from vistac_learn.data.rotations import ROTATION_MODES
from vistac_learn.experiments import cells as C
from vistac_learn.train.config import FREEZE, TrainCfg
from vistac_learn.train.job import JobCfg, JobResult, ScoreCfg

KIND = "sim2real"
METRICS = ("test_angle_deg", "test_in_cone_pct", "val_angle_deg", "sim_test_angle_deg")


@dataclass(frozen=True)
class Sim2RealCfg(Config):
    """The settings of a sim-to-real experiment (the runs' come from the base `TrainCfg`)."""

    sim: str = param(help="simulated dataset: pretraining, and the sim-only model")
    real: str = param(help="real (target-domain) dataset: fine-tuning, training from scratch "
                      "and the test split every model is scored on")
    out: str = param(help="experiment folder")
    fractions: tuple[float, ...] = param((0.1, 0.33, 1.0), gt=0, le=1,
                                         help="fractions of the real training split",
                                         distinct="fraction")
    seeds: int = param(3, ge=1, le=1000, help="seeds per cell (0 .. N-1)")
    freeze: str = param("none", choices=FREEZE, help="fine-tuning: train everything (none) or "
                        "keep the pretrained feature layers fixed (features)")
    sim_epochs: int | None = param(None, ge=1, le=100_000, help="epochs of the sim-only "
                                   "(pretraining) runs (default: --epochs)")
    sim_rotations: str | None = param(None, choices=ROTATION_MODES, help="rotations of the "
                                      "sim-only runs (default: --rotations), e.g. random with "
                                      "--sim-n-rotations 1 on a large simulated dataset")
    sim_n_rotations: int | None = param(None, ge=1, le=360, help="samples per configuration "
                                        "of the sim-only runs (default: --n-rotations)")

    def __post_init__(self) -> None:
        super().__post_init__()
        if Path(self.sim).resolve() == Path(self.real).resolve():
            raise ConfigError("real", "must be another dataset than --sim")


SIM_FIELDS = {"sim_epochs": "epochs", "sim_rotations": "rotations",
              "sim_n_rotations": "n_rotations"}  # Sim2RealCfg field -> TrainCfg field


def pretrain_cfg(cfg: Sim2RealCfg, base: TrainCfg) -> TrainCfg:
    """The sim-only runs' settings: `base` on the simulated dataset, with the ``sim_*``
    overrides of `cfg` (data, out and seed are set per cell).

    Raises:
        UserError: an override that the runs' settings do not allow, naming its option.
    """
    changes = {t: getattr(cfg, f) for f, t in SIM_FIELDS.items() if getattr(cfg, f) is not None}
    try:
        return dataclasses.replace(base, data=cfg.sim, train_fraction=1.0, init=None,
                                   freeze="none", **changes)
    except ConfigError as exc:
        name = next((f for f, t in SIM_FIELDS.items() if t == exc.key and t in changes),
                    exc.key)
        raise UserError(f"--{name.replace('_', '-')}: {exc.reason}") from None


def make_cells(cfg: Sim2RealCfg, base: TrainCfg) -> list[C.Cell]:
    """Every cell of the experiment, in report order (`base`'s data and out are replaced)."""
    out = Path(cfg.out).absolute() / "runs"
    real_test = ScoreCfg("real-test", "test", data=cfg.real)
    pretrain = pretrain_cfg(cfg, base)
    cells = []
    for s in range(cfg.seeds):
        run = dataclasses.replace(pretrain, out=str(out / "sim" / f"seed-{s}"), seed=s)
        cells.append(C.Cell(f"sim-only/0/{s}", {"arm": "sim-only", "fraction": 0.0, "seed": s},
                            JobCfg(run, (real_test, ScoreCfg("sim-test", "test")))))
    for f in sorted(cfg.fractions):
        for s in range(cfg.seeds):
            sim_run = str(out / "sim" / f"seed-{s}")
            for arm in ("scratch", "finetune"):
                init = sim_run if arm == "finetune" else None
                run = dataclasses.replace(
                    base, data=cfg.real, out=str(out / arm / f"fraction-{f:g}" / f"seed-{s}"),
                    seed=s, train_fraction=f, init=init,
                    freeze=cfg.freeze if init else "none")
                cells.append(C.Cell(f"{arm}/{f:g}/{s}", {"arm": arm, "fraction": f, "seed": s},
                                    JobCfg(run, (ScoreCfg("real-test", "test"),)),
                                    phase=1 if init else 0,
                                    needs=f"sim-only/0/{s}" if init else None))
    return cells


def measure(cell: C.Cell, res: JobResult) -> dict[str, float]:
    """A finished cell's numbers (angles: median angle to the cone mean, deg, mean of fingers)."""
    sim = res.score("sim-test") if "sim-test" in res.scores else float("nan")
    return {"test_angle_deg": res.score("real-test"),
            "test_in_cone_pct": res.score("real-test", "in_cone_pct"),
            "val_angle_deg": res.objective, "sim_test_angle_deg": sim}


def run_sim2real(cfg: Sim2RealCfg, base: TrainCfg, runner: Any = None,
                 max_cells: int | None = None, progress: bool = True) -> list[dict[str, Any]]:
    """Run (or continue) the experiment in ``cfg.out``; return the rows of ``cells.csv``.

    Args:
        cfg: The experiment's settings (dataset paths absolute, see `resolved`).
        base: The runs' training settings (data, out, seed, fraction and init are set per cell).
        runner: Runs the training jobs (default `LocalJobRunner`; a Ray runner works alike).
        max_cells: Stop after this many new cells (a rerun continues).
        progress: Show a progress bar.

    Raises:
        UserError: an --out holding another experiment or other settings, bad data.
    """
    with hold(cfg.out, "experiment"):
        out = C.open_experiment(cfg, base, KIND)
        cells = make_cells(cfg, base)

        def on_rows(rows: list[dict[str, Any]]) -> None:
            write_outputs(out, cfg, base, rows)

        return C.run_cells(out, cells, METRICS, measure, on_rows, runner, max_cells, progress)


def resolved(cfg: Sim2RealCfg) -> Sim2RealCfg:
    """The config with absolute dataset paths (recorded, and used by every run)."""
    return dataclasses.replace(cfg, sim=str(Path(cfg.sim).resolve()),
                               real=str(Path(cfg.real).resolve()))


def write_outputs(out: Path, cfg: Sim2RealCfg, base: TrainCfg,
                  rows: list[dict[str, Any]]) -> None:
    """results.csv, report.md and sim2real.png from the finished rows."""
    from vistac_learn.experiments.plots import plot_sim2real

    summary = C.summarise(rows, ("arm", "fraction"), METRICS)
    cols = ["arm", "fraction", "n", *(f"{m}_{s}" for m in METRICS for s in ("mean", "std"))]
    C.write_rows(out / "results.csv", summary, cols)
    plot_sim2real(summary, out / "sim2real.png")
    (out / "report.md").write_text(report(cfg, base, summary, len(rows)))


def _find(summary, arm: str, fraction: float | None = None) -> dict | None:
    return next((s for s in summary if s["arm"] == arm
                 and (fraction is None or abs(s["fraction"] - fraction) < 1e-9)), None)


def report(cfg: Sim2RealCfg, base: TrainCfg, summary: list[dict], n_rows: int) -> str:
    """The markdown report: settings, table, domain gap, finding."""
    n_total = cfg.seeds * (1 + 2 * len(cfg.fractions))
    lines = [
        "# Sim-to-real: pretrain on simulation, fine-tune on a fraction of the real data", "",
        f"- sim: `{cfg.sim}`", f"- real: `{cfg.real}`",
        f"- fractions of the real training split: {', '.join(f'{f:g}' for f in cfg.fractions)}"
        f"; seeds: {cfg.seeds}; fine-tuning freezes: {cfg.freeze}",
        f"- training: model {base.model}, view {base.variant}, fingers {base.finger}, "
        f"{base.epochs} epochs, batch {base.batch_size}, lr {base.lr:g}",
        *_pretraining(cfg, base),
        f"- cells finished: {n_rows} of {n_total}", "",
        "Real test split; angle: median angle to the cone mean (deg, mean of the fingers; "
        "lower is better); mean ± std over seeds.", "",
        "| model | real training data | seeds | real test angle (deg) | real test in cone (%) "
        "|", "|---|---|---|---|---|"]
    for s in summary:
        what = {"sim-only": "sim only (zero-shot)", "scratch": "from scratch",
                "finetune": "sim-pretrained, fine-tuned"}[s["arm"]]
        frac = "none" if s["arm"] == "sim-only" else f"{s['fraction']:g}"
        lines.append(f"| {what} | {frac} | {s['n']} | "
                     f"{C.pm(s['test_angle_deg_mean'], s['test_angle_deg_std'])} | "
                     f"{C.pm(s['test_in_cone_pct_mean'], s['test_in_cone_pct_std'])} |")
    lines += ["", "\n\n".join(findings(cfg, summary)), "", "![sim2real](sim2real.png)", ""]
    return "\n".join(lines)


def findings(cfg: Sim2RealCfg, summary: list[dict]) -> list[str]:
    """Sentences: the domain gap and whether pretraining plus ~1/3 of the data matches all."""
    out = []
    sim, full = _find(summary, "sim-only"), _find(summary, "scratch", max(cfg.fractions))
    if sim and full and sim["n"] and full["n"]:
        a, b = sim["sim_test_angle_deg_mean"], sim["test_angle_deg_mean"]
        c = full["test_angle_deg_mean"]
        side = "worse" if b > c else "better"
        out.append(
            f"**Domain gap**: the sim-only model's median angle is "
            f"{C.pm(a, sim['sim_test_angle_deg_std'])} deg on its own (sim) test split and "
            f"{C.pm(b, sim['test_angle_deg_std'])} deg on the real test split ({b - a:+.1f} deg "
            f"from the change of domain); trained from scratch on {_part(max(cfg.fractions))} "
            f"of the real training data, a model reaches "
            f"{C.pm(c, full['test_angle_deg_std'])} deg there, so zero-shot is {abs(b - c):.1f} "
            f"deg {side}.")
    small = [f for f in cfg.fractions if f < max(cfg.fractions)]
    third = min(small, key=lambda f: abs(f - 1 / 3)) if small else None
    ft = _find(summary, "finetune", third) if third is not None else None
    if ft and full and ft["n"] and full["n"]:
        a, b = ft["test_angle_deg_mean"], full["test_angle_deg_mean"]
        verdict = "at least as well as" if a <= b else "worse than"
        out.append(
            f"**Finding**: pretraining on simulation plus {_part(third)} of the real training "
            f"data ({C.pm(a, ft['test_angle_deg_std'])} deg) does {verdict} training from "
            f"scratch on {_part(max(cfg.fractions))} of it "
            f"({C.pm(b, full['test_angle_deg_std'])} deg).")
    gains = []
    for f in sorted(cfg.fractions):
        sc, fi = _find(summary, "scratch", f), _find(summary, "finetune", f)
        if sc and fi and sc["n"] and fi["n"]:
            gains.append(f"{f:g}: {sc['test_angle_deg_mean'] - fi['test_angle_deg_mean']:+.1f}")
    if gains:
        out.append("Gain of pretraining over from scratch per fraction (deg, positive: "
                   f"pretraining better): {'; '.join(gains)}.")
    if not out:
        out.append("No finding yet: too few cells have finished.")
    return out


def _pretraining(cfg: Sim2RealCfg, base: TrainCfg) -> list[str]:
    """A report line for the sim-only runs' own epochs and rotations (none when they have
    the real runs')."""
    if all(getattr(cfg, f) is None for f in SIM_FIELDS):
        return []
    sim = pretrain_cfg(cfg, base)
    turns = ("no rotations" if sim.rotations == "none"
             else f"{sim.rotations} rotations x {sim.n_rotations}")
    return [f"- sim-only (pretraining) runs: {sim.epochs} epochs, {turns}"]


def _part(fraction: float) -> str:
    return "all" if fraction == 1 else f"{fraction:g}"


def check_inputs(cfg: Sim2RealCfg) -> None:
    """Both datasets are complete before any work.

    Raises:
        UserError: naming the option.
    """
    from vistac.dataset import read_manifest

    for flag, path in (("--sim", cfg.sim), ("--real", cfg.real)):
        try:
            read_manifest(Path(path))
        except UserError as exc:
            raise UserError(f"{flag} {exc}") from None
