"""vistac_sim: MuJoCo scenes of a two-finger hand pressing rigid objects, top-view renders and
fingertip force labels written as datasets."""

import os

# MuJoCo picks its GL backend at import time; EGL works headless on the machines we target.
os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("PYOPENGL_PLATFORM", os.environ["MUJOCO_GL"])

__version__ = "0.1.0"
