"""`vistac ingest`: RH8D/FTS-3 recordings (or the study's label spreadsheets) + images -> dataset.

The study's tactile preprocessing (docs/study.md, section 3), made automatic:

1. Read each recording CSV (one header line; force columns from a `ColumnMap`, by default
   the layout of docs/dataset-format.md; integer mN by default).
2. Split the series into grasps: a grasp starts where |index F_z| rises above `threshold` and
   ends where it falls back to or below it; empty segments cannot occur (each segment has at
   least one sample above the threshold).
3. Representative sample of a grasp: the first local extremum of index F_z that lies beyond the
   segment's mean index F_z (a trough when the mean is negative, a peak when it is positive).
   A run of equal samples counts as one value (quantised readings are often flat at the top); the
   sample is the run's first. The segment's first and last runs have no neighbour on one side
   and are never extrema.
4. The study's by-eye rejection is replaced by these criteria, checked in this order; the first
   that applies is the grasp's reason (`REASONS`):

   - ``too_short``: fewer than `min_samples` samples above the threshold (a knock or a glitch);
   - ``truncated``: the segment touches the first or last sample of the recording (the press
     began before or ended after the recording, so its peak may be missing);
   - ``saturated``: some force component of either finger reaches `saturation` in magnitude
     anywhere in the segment (the FTS-3 range ends at 10 N; the reading is clipped);
   - ``no_extremum``: no local extremum beyond the mean (e.g. a monotonic ramp);
   - ``below_resolution``: at the representative sample a finger's |(F_y, F_z)| is below
     `min_force` (its direction is not resolved: at 20 mN the 1 mN grid alone moves it up to
     ~3 degrees; the thumb may also simply not touch);
   - ``pulling``: at the representative sample a finger's F_z >= 0 (the surface can only push,
     F_z < 0 in contact; docs/dataset-format.md). Off with `allow_pulling`.

5. Each kept grasp becomes a press: forces in N (sensor frame) and the unit labels
   r = (F_y, F_z)/|(F_y, F_z)| per finger (`vistac.dataset.unit_labels`, as `generate`).
   |(F_y, F_z)| = 0 cannot pass ``below_resolution``.

Repeats are numbered by segment, rejected ones included (the k-th grasp of a recording is
``repeat`` k), so that ingested presses join generated ones on (`config_id`, `repeat`). A
configuration keeps the id its file names (``000123.csv`` <-> ``000123.png``: 123), whatever
the other files are called; names that are not numbers are numbered after the largest number
name (from 0 when there is none) in name order, and every name stays in the `recording` column.
Configurations without a kept grasp are left out (a dataset's configuration needs presses) and
listed in the manifest. Every rejected grasp is listed in ``rejected.csv`` (and counted by reason
in the manifest).

With ``--labels FILE.xlsx`` (the study's spreadsheets: one row per grasp, image name, r_y index,
r_z index, r_y thumb, r_z thumb): without recordings the spreadsheet's rows are the presses (no
forces); with recordings they are checked against the ingested labels per configuration (angle
between the mean directions, grasp counts) in the configuration table and the manifest.

Columns only simulation knows (``bbox_*``, ``force_clean_*``, ``normal_*``, ``camera_*``,
``px_per_m``) are NaN. The dataset is built in a hidden temporary folder next to ``--out`` and
renamed into place at the end, its manifest written last: an error or an interruption leaves no
half-written dataset behind.

Modules: `config` (the knobs and sources), `preprocess` (grasps and rejection criteria),
`readers` (recordings, spreadsheets, object lists, with errors naming file and line), `run` (the
dataset), `command` (the CLI). Nothing here imports MuJoCo.
"""
