"""vistac_sim: MuJoCo scenes of a two-finger hand pressing rigid objects, top-view renders and
fingertip force labels written as datasets.

Sub-packages follow the data's way through `vistac generate`:

- `objects`: procedural outlines and user meshes, with convex collision pieces;
- `hand`: the hand's MJCF asset edited per config, the object added, compiled; grasps;
- `physics`: the press, its checks and the surface-normal look-up;
- `render`: the orthographic top view, exact finger boxes, PNG encoding, effect views;
- `effects`: the effect registry and one small module per effect, presets and scene files;
- `recording`: the 50 Hz press session and its RH8D/FTS-3 recording CSV;
- `generate`: grasp sampling, one configuration end to end, workers, shards and resume.

MuJoCo is imported through `vistac_sim.mj` only (it picks the headless GL backend).
"""

from vistac import __version__

__all__ = ["__version__"]
