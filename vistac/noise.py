"""The force measurement noise model (``--noise S``), free of MuJoCo and torch.

One owner for the simulator's per-press noise (`vistac_sim.effects.noise.ForceNoise`) and the
learner's label-noise experiment (`vistac experiment label-noise`), which draws the same noise
from a dataset's clean forces instead of simulating again.
"""

from __future__ import annotations

import numpy as np


def relative_force_noise(forces: np.ndarray, relative_std: float,
                         rng: np.random.Generator) -> np.ndarray:
    """Forces with independent Gaussian noise on each component, relative to their magnitude.

    Each component of each force vector gets noise of standard deviation ``relative_std * |F|``
    (the magnitude of that vector).

    Args:
        forces: (..., 3) force vectors (N).
        relative_std: Noise std as a fraction of the magnitude (0: no noise, `forces` copied).
        rng: Source of the draws (``forces.size`` standard normals, in C order).

    Returns:
        (..., 3) noisy forces.
    """
    forces = np.asarray(forces, float)
    scale = relative_std * np.linalg.norm(forces, axis=-1, keepdims=True)
    return forces + scale * rng.standard_normal(forces.shape)
