"""vistac: visuo-tactile datasets from MuJoCo and learning on them.

This small core package is what both halves share and what the `vistac` console command starts
from; it imports neither MuJoCo nor torch:

- `vistac.cli`: the `vistac` command (each sub-command imported only when chosen);
- `vistac.errors`: `UserError`, bad input reported in one line;
- `vistac.config`: typed, self-validating config dataclasses (each parameter declared once);
- `vistac.dataset`: the dataset format (schema, labels, manifest, readers and writers).

The simulator is `vistac_sim`, the learner `vistac_learn`.
"""

__version__ = "0.1.0"
