"""Whether a run's training labels lean to one side, which mirroring would hide.

The default recipe mirrors half of its training samples and averages each test image with its
mirror (`TrainCfg.mirror`, `TrainCfg.tta`): a mirror flips r_y, so the recipe assumes that a
finger's label is as likely to lean one way as the other. A hand that pulls its finger sideways
while pressing (the reference study saw it on its FTS-3 recordings; the simulator's
``finger_pull`` effect) breaks that: every label leans the same way, and mirroring averages the
lean out. On the study twin (``sim_assets/scenes/study.yaml``, labels leaning +8 degrees) the
recipe with mirroring scores no better than the clean force; without it (``--no-mirror
--no-tta``, and ``--aux-weight 0`` where the simulator's unleaned contact geometry would pull
against the labels) it learns the lean (`benchmarks/study_curve.py`).

`label_lean` measures the lean as the mean r_y of the training labels and its standard error;
`lean_note` says so at the start of a run that mirrors when the lean is both large and
certain.
"""

from __future__ import annotations

import numpy as np

LEAN_MIN = 0.05  # |mean r_y| of unit labels worth a note: about 3 degrees
LEAN_SIGMAS = 5.0  # and this many standard errors away from no lean


def label_lean(labels: dict[str, np.ndarray]) -> dict[str, dict]:
    """Per finger, the mean r_y of the (N, 2) unit labels (r_y, r_z), its standard error and N
    (finite labels only)."""
    out = {}
    for finger, yz in labels.items():
        ry = np.asarray(yz, dtype=float)[:, 0]
        ry = ry[np.isfinite(ry)]
        n = len(ry)
        out[finger] = {"mean_r_y": float(ry.mean()) if n else float("nan"),
                       "stderr": float(ry.std(ddof=1) / np.sqrt(n)) if n > 1 else float("inf"),
                       "n": n}
    return out


def leaning(lean: dict[str, dict]) -> list[str]:
    """The fingers whose labels lean: |mean r_y| >= `LEAN_MIN` and >= `LEAN_SIGMAS` standard
    errors."""
    return [f for f, v in lean.items()
            if abs(v["mean_r_y"]) >= LEAN_MIN and abs(v["mean_r_y"]) >= LEAN_SIGMAS * v["stderr"]]


def lean_note(lean: dict[str, dict], mirror: bool, tta: bool) -> str | None:
    """A line for the start of a run whose mirroring (`mirror`, `tta`) would hide a lean of its
    training labels; None when nothing leans or nothing is mirrored."""
    fingers = leaning(lean)
    if not fingers or not (mirror or tta):
        return None
    what = ", ".join(f"{f} mean r_y {lean[f]['mean_r_y']:+.3f} ± {lean[f]['stderr']:.3f} "
                     f"({np.degrees(np.arcsin(np.clip(lean[f]['mean_r_y'], -1, 1))):+.1f} deg, "
                     f"{lean[f]['n']} configurations)" for f in fingers)
    on = " and ".join(o for o, v in (("--mirror", mirror), ("--tta", tta)) if v)
    return (f"the training labels lean to one side ({what}); {on} flip r_y and average the "
            "lean out: --no-mirror --no-tta keep it (a hand pulling its finger sideways, as "
            "the reference study saw; docs/learner.md)")
