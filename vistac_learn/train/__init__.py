"""Training: a run's settings (`config`: `TrainCfg`, the model and pairs it builds), the loop with
validation-based selection, checkpoints and exact resume (`loop`: `train_run_folder`), and the CLI
(`command`)."""
