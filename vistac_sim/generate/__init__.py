"""`vistac generate`: from a validated config to a dataset directory.

- `config`: `GenerateCfg`, the whole config tree (written into the manifest);
- `grasps`: grasp sampling on an object's outline;
- `scenes`: what a worker builds once per object, and pressing a grasp (`solve`, `draw_grasp`);
- `configuration`: one grasp configuration end to end (presses, effects, labels, render, rows);
- `shards`: the unfinished run's state, committed shards, resume and the final tables;
- `run`: chunks of configurations in worker processes (`generate`);
- `command`: the CLI options and handler.
"""
