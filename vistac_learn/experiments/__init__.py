"""The user's experiments (`vistac experiment ...`): grids of training jobs with a report.

- `vistac_learn.experiments.cells`: the resumable grid of jobs (`Cell`, `run_cells`) and the
  mean +- std summary over seeds;
- `vistac_learn.experiments.sim2real`: sim-pretrained then fine-tuned against from scratch, per
  fraction of the real training data;
- `vistac_learn.experiments.label_noise`: accuracy against the level of label noise drawn by
  the generator's own noise model (`vistac.noise`);
- `vistac_learn.experiments.plots`: the error-bar figures;
- `vistac_learn.experiments.command`: the command line.
"""
