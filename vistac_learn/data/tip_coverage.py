"""No score without data: configurations whose fingertips were not found, counted and gated.

A configuration whose finger the locator (`vistac_learn.data.fingertips`) does not find in its
image (an all-black, grey or tiny image, a finger drawn in another colour) has no input for the
tip view: its sample is masked out of the loss and the scores. A few such images in a large
dataset are harmless; many of them make a loss and a score that describe nothing (an all-black
dataset trained to "loss 0"). So every learning command counts them per split (`tip_coverage`),
says so (`TipCoverage.line`), and training and evaluation stop before any work when a split's
share is above a threshold (`TipCoverage.check`, ``--max-missing-pct``, default 1 %). The finger
boxes located where a dataset has none (`vistac_learn.data.located_boxes`, for the study's
views) are counted and gated the same way.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

from vistac.dataset import DatasetTables
from vistac.dataset.schema import CONFIGS
from vistac.errors import UserError
from vistac_learn.data.fingertip_table import FingertipTable
from vistac_learn.data.located_boxes import BoxTable

MAX_MISSING_PCT = 1.0
"""Default largest share (%) of a split's configurations whose fingertips were not found."""


@dataclass(frozen=True)
class TipCoverage:
    """The configurations of one split whose fingertips were not found.

    Attributes:
        split: The split's name.
        n: Configurations of the split.
        missing: Configurations of which at least one finger used was not found.
        per_finger: Finger -> configurations where that finger was not found.
        example: Image file of the first such configuration, or "".
        reason: Why that finger was not found, or "".
        what: What was looked for: ``fingertips``, or ``finger boxes`` (located where the
            dataset has none).
    """

    split: str
    n: int
    missing: int
    per_finger: dict[str, int] = field(default_factory=dict)
    example: str = ""
    reason: str = ""
    what: str = "fingertips"

    @property
    def pct(self) -> float:
        """The share of configurations with a finger not found, in percent."""
        return 100.0 * self.missing / max(self.n, 1)

    def line(self) -> str:
        """One line saying how many were not found, and an example."""
        if not self.missing:
            return f"{self.what} found in all {self.n} configurations of the {self.split} split"
        fingers = ", ".join(f"{f} {k}" for f, k in self.per_finger.items() if k)
        return (f"{self.what} not found in {self.missing} of {self.n} configurations "
                f"({self.pct:.3g} %) of the {self.split} split ({fingers}), e.g. {self.example} "
                f"({self.reason})")

    def check(self, max_pct: float, option: str = "--max-missing-pct") -> None:
        """Refuse a split whose share of configurations not found is above `max_pct`.

        Raises:
            UserError: the count, an example image and what to do, on one line.
        """
        if self.missing and self.pct > max_pct:
            raise UserError(f"{self.line()}: above {option} {max_pct:g}; check or remove those "
                            f"images (rows of {CONFIGS}), or raise {option}")

    def as_dict(self) -> dict:
        """The counts for a run's ``config.json`` or an evaluation's ``metrics.json``."""
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> TipCoverage:
        """The counts `as_dict` wrote."""
        return cls(**d)


def tip_coverage(tables: DatasetTables, tips: FingertipTable | BoxTable, rows: np.ndarray,
                 fingers: tuple[str, ...], split: str) -> TipCoverage:
    """Count the configurations among `rows` whose fingers (of `fingers`) were not found (in a
    fingertip table, or a table of finger boxes)."""
    what = "finger boxes" if isinstance(tips, BoxTable) else "fingertips"
    rows = np.asarray(rows, dtype=np.int64)
    ok = np.stack([tips.frame[f"{f}_ok"].to_numpy(bool)[rows] for f in fingers], axis=1) \
        if len(rows) else np.ones((0, len(fingers)), bool)
    lost = ~ok.all(axis=1)
    per = {f: tips.failures(rows, f) for f in fingers}
    if not lost.any():
        return TipCoverage(split, len(rows), 0, per, what=what)
    first = int(rows[np.flatnonzero(lost)[0]])
    finger = next(f for f in fingers if not tips.get(first, f).ok)
    return TipCoverage(split, len(rows), int(lost.sum()), per, str(tables.image_path(first)),
                       f"{finger}: {tips.get(first, finger).reason}", what)
