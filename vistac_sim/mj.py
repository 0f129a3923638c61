"""MuJoCo, imported the one way the simulator does: ``from vistac_sim.mj import mujoco``.

MuJoCo picks its GL backend when it is imported; EGL works headless on the machines we target,
so it is the default here (an environment that sets ``MUJOCO_GL`` keeps its choice). MuJoCo
would also append its warnings to ``MUJOCO_LOG.TXT`` in the working directory; every solve checks
the warning counters and rejects the sample (`vistac_sim.physics.press`), so the text only goes
to the log.
"""

import logging
import os
import warnings

from vistac.errors import UserError

os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("PYOPENGL_PLATFORM", os.environ["MUJOCO_GL"])


def gl_error(reason: str) -> str:
    """The one line for a GL backend (``MUJOCO_GL``) that cannot start: the variable, why, and
    what to set."""
    return (f"MUJOCO_GL={os.environ.get('MUJOCO_GL', '')}: MuJoCo cannot render with this "
            f"backend here ({reason[:110]}); unset MUJOCO_GL (vistac then uses egl, which needs "
            "no display) or set MUJOCO_GL=egl, or osmesa with its library installed")


try:  # MuJoCo loads the backend's library on import: an unknown or missing one fails here
    import mujoco
    from mujoco.rendering.classic import gl_context  # (one GL context per process)
except Exception as exc:  # noqa: BLE001 - RuntimeError, ImportError, PyOpenGL's AttributeError
    raise UserError(gl_error(" ".join(str(exc).split()) or type(exc).__name__)) from None
warnings.filterwarnings("ignore", module="glfw")  # its complaints at exit, after a failed glx

_LOG = logging.getLogger("vistac_sim.mujoco")
mujoco.set_mju_user_warning(lambda msg: _LOG.debug("MuJoCo warning: %s", msg))

__all__ = ["gl_context", "gl_error", "mujoco"]
