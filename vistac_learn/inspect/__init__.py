"""`vistac inspect`: see a dataset, its recordings, or where a run's model fails.

- `readable`: a dataset read as far as it is readable, with a note per unreadable part;
- `arrows`: each fingertip's place and axis in the image and its labels as image directions
  (the frame convention is `vistac.dataset.frames`);
- `drawing`: arrows, cones, mask outlines, captions and grids on images;
- `sheet`: the contact sheet of sampled configurations per split and family;
- `distributions`: label angle, cone width and force magnitude by family and split, rejection
  reasons, the image effects' draws (figures);
- `summary`: the summary lines;
- `runs`: the worst configurations of a run's evaluation;
- `report`: the report folders and their `report.md`; `config`: `InspectCfg`; `command`: the CLI.

The recordings pages (50 Hz series, segments, chosen samples, rejection reasons) belong to
ingest: `vistac.dataset.ingest.pages` (also `vistac ingest --report`). See docs/inspect.md.
"""
