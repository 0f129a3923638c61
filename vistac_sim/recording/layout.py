"""Recording CSVs in the RH8D/FTS-3 layout (docs/dataset-format.md): one header line, one line
per sample.

Columns (0-based): 0 time in ms, 1 sample number, 2-9 servo positions of the RH8D's eight
actuators (ticks, 0-4095), 10-13 servo currents of thumb adduction/flexion, index and middle
flexion (mA), 14-16 thumb F_x, F_y, F_z and 17-19 index F_x, F_y, F_z (integer mN, sensor frame).
Servo columns are plausible fillers (idle values; the flexion servos follow the press) that no
tool reads. A configuration's file is `recordings/NNNNNN.csv`, NNNNNN its `config_id`, so that
ingested presses join generated ones on (`config_id`, `repeat`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from vistac.dataset import FINGERS

if TYPE_CHECKING:
    from vistac_sim.recording.session import Session

SERVOS = ("wrist_rotation", "wrist_adduction", "wrist_flexion", "thumb_adduction",
          "thumb_flexion", "index_flexion", "middle_flexion", "ring_little_flexion")
CURRENTS = ("thumb_adduction", "thumb_flexion", "index_flexion", "middle_flexion")
FORCE_COLUMNS = {"thumb": (14, 15, 16), "index": (17, 18, 19)}
HEADER = ["time_ms", "sample", *(f"pos_{s}" for s in SERVOS),
          *(f"current_{s}_ma" for s in CURRENTS),
          *(f"{f}_f{c}_mn" for f in ("thumb", "index") for c in "xyz")]


def recording_name(config_id: int) -> str:
    """File name of configuration `config_id`'s recording."""
    return f"{config_id:06d}.csv"


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
