"""`vistac generate`: from a validated config to a dataset directory.

- `config`: `GenerateCfg`, the whole config tree (written into the manifest);
- `grasps`: grasp sampling on an object's outline;
- `rigs`: what a worker builds once per object (`ObjectRig`), and pressing a grasp (`solve`,
  `draw_grasp`);
- `configuration`: one grasp configuration end to end (presses, effects, labels, render, rows);
- `shards`: the unfinished run's state, committed shards, resume and the final tables;
- `objects_report`: which objects a run keeps, and the per-object summary at its end;
- `run`: the driver: plans chunks of configurations and hands them to workers (`generate`);
  it imports no simulator;
- `worker`: what a worker process does: screen an object, make and commit chunks;
- `on_ray`: the same chunks as Ray tasks;
- `command`: the CLI options and handler.
"""
