"""vistac_learn: image variants, CNN model zoo, training and cone-metric evaluation on vistac
datasets (simulated or ingested from real RH8D/FTS-3 recordings).

- `data`: the study's image variants, their cache, and (configuration, rotation) pairs;
- `models`: the registry (`create_model`), MAC counting, the study's nets and the baselines;
- `train`: `TrainCfg` and the training loop (validation-based selection, exact resume);
- `metrics`: the study's cone metrics plus angular metrics, and scoring of predictions;
- `evaluate`: scoring a run or the geometric baseline, figures;
- `demo`: `vistac demo`, the main job end to end.

Reading datasets is `vistac.dataset`; nothing here imports MuJoCo.
"""

from vistac import __version__

__all__ = ["__version__"]
