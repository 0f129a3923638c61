"""A simulated session as a recording CSV in the RH8D/FTS-3 layout of
`vistac.dataset.recordings` (docs/dataset-format.md).

Servo columns are plausible fillers (idle values; the flexion servos follow the press) that no
tool reads.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from vistac.dataset import FINGERS
from vistac.dataset.recordings import CURRENTS, FORCE_COLUMNS, HEADER, SERVOS

if TYPE_CHECKING:
    from vistac_sim.recording.session import Session


def recording_table(session: Session) -> np.ndarray:
    """(T, 20) integer table of a session in the column layout above."""
    n = len(session.measured)
    env = session.envelope
    table = np.zeros((n, len(HEADER)), dtype=np.int64)
    table[:, 0] = np.round(np.arange(n) * session.dt * 1000.0)
    table[:, 1] = np.arange(n)
    table[:, 2:10] = 2048
    flex = np.round(2048 + 600 * env).astype(np.int64)
    table[:, 2 + SERVOS.index("thumb_flexion")] = flex
    table[:, 2 + SERVOS.index("index_flexion")] = flex
    table[:, 10:14] = 25
    load = np.round(25 + 300 * env).astype(np.int64)
    table[:, 10 + CURRENTS.index("thumb_flexion")] = load
    table[:, 10 + CURRENTS.index("index_flexion")] = load
    for finger, cols in FORCE_COLUMNS.items():
        table[:, list(cols)] = np.round(session.measured[:, FINGERS.index(finger)] * 1000.0)
    return table


def recording_csv(session: Session) -> bytes:
    """The CSV bytes of a session (header line + integer rows, comma separated)."""
    table = recording_table(session)
    row = ",".join(["%d"] * table.shape[1]) + "\n"
    return (",".join(HEADER) + "\n" + (row * len(table)) % tuple(table.ravel().tolist())).encode()
