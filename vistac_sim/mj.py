"""MuJoCo, imported the one way the simulator does: ``from vistac_sim.mj import mujoco``.

MuJoCo picks its GL backend when it is imported; EGL works headless on the machines we target,
so it is the default here (an environment that sets ``MUJOCO_GL`` keeps its choice). MuJoCo
would also append its warnings to ``MUJOCO_LOG.TXT`` in the working directory; every solve checks
the warning counters and rejects the sample (`vistac_sim.physics.press`), so the text only goes
to the log.
"""

import logging
import os

os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("PYOPENGL_PLATFORM", os.environ["MUJOCO_GL"])

import mujoco  # noqa: E402
from mujoco.rendering.classic import gl_context  # noqa: E402  (one GL context per process)

_LOG = logging.getLogger("vistac_sim.mujoco")
mujoco.set_mju_user_warning(lambda msg: _LOG.debug("MuJoCo warning: %s", msg))

__all__ = ["gl_context", "mujoco"]
