"""`vistac generate`: from a validated config to a dataset directory.

- `config`: `GenerateCfg`, the whole config tree (written into the manifest);
- `plan`: chunks of configurations, tasks of chunks, the versions that decide the bytes (pure);
- `grasps`: grasp sampling on an object's outline;
- `rigs`: what a worker builds once per object (`ObjectRig`), and pressing a grasp (`solve`,
  `draw_grasp`);
- `configuration`: one grasp configuration end to end (presses, effects, labels, render, rows);
- `screening`: one object built and checked for a valid grasp, before a run;
- `chunks`: chunk work: make a chunk in memory, commit it (`ChunkWork`, the job of a runner);
- `shards`: the unfinished run's state, committed shards, resume and the final tables;
- `objects_report`: which objects a run keeps, and the per-object summary at its end;
- `run`: the driver: screens, plans and hands tasks to a runner of `vistac.engine` (`generate`);
  it imports no simulator;
- `on_ray`: the same chunks as Ray tasks;
- `command`: the CLI options and handler.

See docs/generation.md for how they depend on each other.
"""

# What the workers' fork server (`vistac.engine.ForkServer`) imports before it forks them: the
# simulator behind chunks and screening, and pandas, which pyarrow imports on its first table
# (a shard): once in the server, not once per worker.
WORKER_MODULES = ("vistac_sim.generate.chunks", "vistac_sim.generate.screening",
                  "vistac_sim.generate.configuration", "vistac_sim.objects.decomposition",
                  "pandas")
