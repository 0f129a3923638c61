"""Index look-ups into a compiled model, per finger where it applies."""

from __future__ import annotations

from dataclasses import dataclass

from vistac.dataset import FINGERS
from vistac_sim.mj import mujoco

OBJECT_GROUP_COLLISION = 3  # geom group of the object's collision pieces (hidden in renders)
LATERAL_JOINTS = ("side", "lift")  # the tip's sprung slides across its push, "<finger>_<name>"


@dataclass
class ModelIds:
    """Index look-ups into a compiled model (element names of `sim_assets/hand/`)."""

    pad: dict[str, int]
    shaft: dict[str, int]
    site: dict[str, int]
    mocap: dict[str, int]
    qpos: dict[str, int]
    dof: dict[str, int]
    tip_dofs: dict[str, slice]  # every dof of the tip body: the push slide, then the lateral ones
    lateral_qpos: list[int]  # qpos addresses of every lateral slide (both fingers)
    holds: list[int]  # equality ids that hold the lateral slides during the approach
    actuator: dict[str, int]
    sensor_adr: dict[str, int]
    object_body: int
    camera: int

    @classmethod
    def of(cls, model: mujoco.MjModel) -> ModelIds:
        def ids(kind, fmt):
            return {f: mujoco.mj_name2id(model, kind, fmt.format(f)) for f in FINGERS}

        obj = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "object")
        joints = ids(mujoco.mjtObj.mjOBJ_JOINT, "{}_slide")
        sensors = ids(mujoco.mjtObj.mjOBJ_SENSOR, "{}_net")
        bodies = ids(mujoco.mjtObj.mjOBJ_BODY, "{}_base")
        return cls(
            pad=ids(mujoco.mjtObj.mjOBJ_GEOM, "{}_pad"),
            shaft=ids(mujoco.mjtObj.mjOBJ_GEOM, "{}_shaft"),
            site=ids(mujoco.mjtObj.mjOBJ_SITE, "{}_sensor"),
            mocap={f: int(model.body_mocapid[b]) for f, b in bodies.items()},
            qpos={f: int(model.jnt_qposadr[j]) for f, j in joints.items()},
            dof={f: int(model.jnt_dofadr[j]) for f, j in joints.items()},
            tip_dofs={f: slice(int(model.jnt_dofadr[j]), int(model.jnt_dofadr[j]) + 1
                               + len(LATERAL_JOINTS)) for f, j in joints.items()},
            lateral_qpos=[int(model.jnt_qposadr[mujoco.mj_name2id(
                model, mujoco.mjtObj.mjOBJ_JOINT, f"{f}_{n}")]) for f in FINGERS
                for n in LATERAL_JOINTS],
            holds=[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_EQUALITY, f"{f}_{n}_hold")
                   for f in FINGERS for n in LATERAL_JOINTS],
            actuator=ids(mujoco.mjtObj.mjOBJ_ACTUATOR, "{}_drive"),
            sensor_adr={f: int(model.sensor_adr[s]) for f, s in sensors.items()},
            object_body=obj,
            camera=mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, "top"),
        )
