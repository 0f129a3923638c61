"""Recording CSVs in the RH8D/FTS-3 layout (docs/dataset-format.md): one header line, one line
per sample.

Columns (0-based): 0 time in ms, 1 sample number, 2-9 servo positions of the RH8D's eight
actuators (ticks, 0-4095), 10-13 servo currents of thumb adduction/flexion, index and middle
flexion (mA), 14-16 thumb F_x, F_y, F_z and 17-19 index F_x, F_y, F_z (integer mN, sensor frame).
A configuration's file is `recordings/NNNNNN.csv`, NNNNNN its `config_id`, so that ingested
presses join generated ones on (`config_id`, `repeat`).

The simulator writes this layout (`vistac_sim.recording.layout`), `vistac ingest` reads it.
"""

from __future__ import annotations

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
