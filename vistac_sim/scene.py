"""The MuJoCo scene of one object: table, static object, two driven fingertips, top camera.

Each fingertip hangs from a mocap base that the grasp places and orients per configuration (local
x = approach direction, local z = world up), and moves on one slide joint along its approach,
pushed by a constant-force motor. The sensor site carries the fingertip sensor frame of
contracts.md: z along the approach (out of the pad, towards the object), y across the finger in
the table plane (mirrored for the thumb), x = y cross z.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from vistac_sim.config import GenerateCfg
from vistac_sim.objects import SceneObject

FINGERS = ("index", "thumb")
OBJECT_GROUP_COLLISION = 3  # geom group of the collision pieces (hidden in renders)

# Sensor frame axes expressed in the fingertip body frame (columns x_s, y_s, z_s).
_SENSOR_FRAMES = {
    "index": np.array([[0, 0, 1], [0, 1, 0], [-1, 0, 0]], float),  # x_s = -z, y_s = y, z_s = x
    "thumb": np.array([[0, 0, 1], [0, -1, 0], [1, 0, 0]], float),  # x_s = z, y_s = -y, z_s = x
}


def sensor_rotation(finger: str, approach_xy: np.ndarray) -> np.ndarray:
    """World-from-sensor rotation (3x3, columns = sensor axes) for a finger and approach."""
    a = np.array([approach_xy[0], approach_xy[1], 0.0])
    a /= np.linalg.norm(a)
    body = np.column_stack([a, np.cross([0.0, 0.0, 1.0], a), [0.0, 0.0, 1.0]])
    return body @ _SENSOR_FRAMES[finger]


def _fmt(values) -> str:
    return " ".join(f"{v:.9g}" for v in np.ravel(values))


def scene_xml(cfg: GenerateCfg) -> str:
    """MJCF of the scene without the object's geoms (`compile_scene` adds them as arrays)."""
    hand, phys, rend = cfg.hand, cfg.physics, cfg.render
    condim = 1 if phys.friction == 0 else 3
    assets = []
    r, hl = hand.tip_radius, hand.tip_half_length
    shaft0 = -2 * hl - 0.5 * hand.shaft_radius
    shaft1 = shaft0 - hand.shaft_length
    fingers = []
    for name, rgb in (("index", rend.index_rgb), ("thumb", rend.thumb_rgb)):
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, _SENSOR_FRAMES[name].ravel())
        fingers.append(f"""
    <body name="{name}_base" mocap="true" pos="0 0 {hand.height}">
      <body name="{name}_tip">
        <joint name="{name}_slide" type="slide" axis="1 0 0" range="0 {hand.standoff + hand.travel}"
               damping="{hand.damping}" limited="true"/>
        <inertial pos="0 0 0" mass="{hand.mass}" diaginertia="1e-6 1e-6 1e-6"/>
        <geom name="{name}_pad" type="capsule" fromto="{-2 * hl} 0 0 0 0 0" size="{r}"
              material="{name}_mat" contype="2" conaffinity="1"/>
        <geom name="{name}_shaft" type="capsule" fromto="{shaft0} 0 0 {shaft1} 0 0"
              size="{hand.shaft_radius}" material="{name}_mat" contype="2" conaffinity="1"/>
        <site name="{name}_sensor" pos="{r} 0 0" quat="{_fmt(quat)}" size="0.002"/>
      </body>
    </body>""")
        assets.append(f'<material name="{name}_mat" rgba="{_fmt(rgb)} 1" emission="1" '
                      f'specular="0" shininess="0"/>')
    sensors = "\n".join(
        f'<contact name="{f}_net" geom1="{f}_pad" body2="object" data="force" reduce="netforce"/>'
        for f in FINGERS
    )
    size = rend.image_size
    return f"""
<mujoco model="vistac_scene">
  <compiler angle="radian" autolimits="true"/>
  <option timestep="{phys.timestep}" cone="elliptic" gravity="0 0 -9.81"/>
  <default>
    <geom condim="{condim}" friction="{phys.friction} 0.005 0.0001"
          solref="{_fmt(phys.solref)}" solimp="{_fmt(phys.solimp)}"/>
  </default>
  <visual>
    <quality shadowsize="0" offsamples="0"/>
    <global offwidth="{size}" offheight="{size}"/>
    <headlight ambient="0.45 0.45 0.45" diffuse="0.55 0.55 0.55" specular="0 0 0"/>
  </visual>
  <asset>
    {chr(10).join(assets)}
  </asset>
  <worldbody>
    <geom name="table" type="plane" size="0.5 0.5 0.01" rgba="{_fmt(rend.table_rgb)} 1"
          contype="0" conaffinity="0"/>
    <camera name="top" pos="0 0 1" projection="orthographic" fovy="{rend.view_extent}"/>
    <body name="object"/>
    {"".join(fingers)}
  </worldbody>
  <actuator>
    <motor name="index_drive" joint="index_slide"/>
    <motor name="thumb_drive" joint="thumb_slide"/>
  </actuator>
  <sensor>
    {sensors}
  </sensor>
</mujoco>"""


@dataclass
class SceneIds:
    """Index look-ups into a compiled scene model, per finger where it applies."""

    pad: dict[str, int]
    shaft: dict[str, int]
    site: dict[str, int]
    mocap: dict[str, int]
    qpos: dict[str, int]
    dof: dict[str, int]
    actuator: dict[str, int]
    sensor_adr: dict[str, int]
    object_body: int
    camera: int

    @classmethod
    def of(cls, model: mujoco.MjModel) -> SceneIds:
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
            actuator=ids(mujoco.mjtObj.mjOBJ_ACTUATOR, "{}_drive"),
            sensor_adr={f: int(model.sensor_adr[s]) for f, s in sensors.items()},
            object_body=obj,
            camera=mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, "top"),
        )


def compile_scene(obj: SceneObject, cfg: GenerateCfg) -> tuple[mujoco.MjModel, SceneIds]:
    """Compile the scene of one object.

    The object's meshes go in as arrays through `MjSpec` (formatting a 300k-face mesh as MJCF
    text and parsing it back costs seconds): the full-resolution visual mesh, which does not
    collide, and the convex pieces, which collide and are hidden in renders (group 3).
    """
    spec = mujoco.MjSpec.from_string(scene_xml(cfg))
    body = spec.body("object")
    phys = cfg.physics
    _add_mesh_geom(spec, body, "object_visual", obj.mesh, (*obj.rgb, 1.0), collide=False, group=0)
    for i, piece in enumerate(obj.pieces):
        g = _add_mesh_geom(spec, body, f"piece{i}", piece, (0, 0, 0, 0), collide=True,
                           group=OBJECT_GROUP_COLLISION)
        g.condim = 1 if phys.friction == 0 else 3
        g.friction = [phys.friction, 0.005, 0.0001]
        g.solref = list(phys.solref)
        g.solimp = [*phys.solimp, 0.5, 2.0]
    model = spec.compile()
    return model, SceneIds.of(model)


def _add_mesh_geom(spec: mujoco.MjSpec, body, name: str, mesh, rgba, collide: bool, group: int):
    asset = spec.add_mesh()
    asset.name = f"{name}_mesh"
    asset.uservert = np.asarray(mesh.vertices, np.float32).ravel()
    asset.userface = np.asarray(mesh.faces, np.int32).ravel()
    g = body.add_geom()
    g.name, g.type, g.meshname = name, mujoco.mjtGeom.mjGEOM_MESH, asset.name
    g.rgba = list(rgba)
    g.group = group
    g.contype = g.conaffinity = int(collide)
    return g
