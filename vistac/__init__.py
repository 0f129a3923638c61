"""vistac: visuo-tactile datasets from MuJoCo and learning on them.

The Python API (the `vistac` command is a thin layer over it)::

    import vistac
    ds  = vistac.generate(vistac.GenerateCfg(n=200, seed=1), out="data/d")     # -> Dataset
    ds  = vistac.open_dataset("data/d")                                         # read back
    run = vistac.train(vistac.TrainCfg(epochs=2), data="data/d", out="runs/r")  # -> Run
    ev  = vistac.evaluate(run)        # ev.metrics == metrics.json's "metrics"

plus `ingest`, `tune`, `sim2real` and `label_noise` (`vistac.api`), and the configs
(`GenerateCfg.from_preset("lab", noise=0.05)`, `.from_file(path)`,
`TrainCfg.from_protocol("study")`, `EvaluateCfg`, ...). Every name is imported on first use, so
``import vistac`` loads neither MuJoCo nor torch; `generate` loads the simulator, `train` torch.

This core package holds what both halves share:

- `vistac.api`, `vistac.outputs`: the functions above and the handles they return;
- `vistac.cli`: the `vistac` command (each sub-command imported only when chosen);
- `vistac.errors`: `UserError`, bad input reported in one line;
- `vistac.config`: typed, self-validating config dataclasses (each parameter declared once);
- `vistac.dataset`: the dataset format (schema, labels, manifest, readers and writers, the
  recording CSV layout) and `vistac.dataset.ingest` (recordings + images -> dataset).

The simulator is `vistac_sim`, the learner `vistac_learn`.
"""

import importlib

__version__ = "0.1.0"

# public name -> module that defines it (imported on first access)
_LAZY = {
    "generate": "vistac.api", "open_dataset": "vistac.api", "ingest": "vistac.api",
    "train": "vistac.api", "evaluate": "vistac.api", "tune": "vistac.api",
    "sim2real": "vistac.api", "label_noise": "vistac.api",
    "Dataset": "vistac.outputs", "Run": "vistac.outputs", "Evaluation": "vistac.outputs",
    "Report": "vistac.outputs",
    "UserError": "vistac.errors",
    "EngineCfg": "vistac.engine",
    "GenerateCfg": "vistac_sim.generate.config",
    "IngestCfg": "vistac.dataset.ingest.config",
    "IngestSources": "vistac.dataset.ingest.config",
    "TrainCfg": "vistac_learn.train.config",
    "EvaluateCfg": "vistac_learn.evaluate.config",
    "TrialCfg": "vistac_learn.tune.engines",
    "Sim2RealCfg": "vistac_learn.experiments.sim2real",
    "LabelNoiseCfg": "vistac_learn.experiments.label_noise",
}
__all__ = ["__version__", *_LAZY]


def __getattr__(name: str):
    """The API's names, imported on first use (see `_LAZY`)."""
    if name in _LAZY:
        value = getattr(importlib.import_module(_LAZY[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'vistac' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))
