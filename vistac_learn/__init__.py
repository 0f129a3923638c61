"""vistac_learn: image variants, CNN model zoo, training and cone-metric evaluation on vistac
datasets (simulated or ingested from real RH8D/FTS-3 recordings)."""

__version__ = "0.1.0"
