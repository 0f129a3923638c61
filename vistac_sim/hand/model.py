"""The model of one object: the hand's MJCF asset, edited from the config, plus the object.

`sim_assets/hand/scene.xml` (table, top camera, the object's body, contact force sensors) includes
`hand.xml` (the two fingertips on mocap bases, a driven slide along the push and two sprung
slides across it, drives, sensor sites). `hand_spec`
loads them as an `MjSpec` and sets every number the config controls; `compile_model` adds the
object's meshes as arrays and compiles. The asset's numbers are the config defaults, so the
default config leaves them as they are.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from vistac.dataset import FINGERS
from vistac_sim.assets import SCENE_XML
from vistac_sim.hand.ids import LATERAL_JOINTS, OBJECT_GROUP_COLLISION, ModelIds
from vistac_sim.mj import mujoco
from vistac_sim.render.materials import add_banks, banks_of, planar_texcoords

if TYPE_CHECKING:
    from vistac_sim.generate.config import GenerateCfg
    from vistac_sim.objects.library import BuiltObject
    from vistac_sim.physics.config import PhysicsCfg


def hand_spec(cfg: GenerateCfg) -> mujoco.MjSpec:
    """The hand's model without the object's geoms, sized, driven and coloured as `cfg` says."""
    spec = mujoco.MjSpec.from_file(str(SCENE_XML))
    hand, phys, rend = cfg.hand, cfg.physics, cfg.render
    spec.option.timestep = phys.timestep
    spec.option.noslip_iterations = phys.noslip_iterations
    spec.visual.global_.offwidth = spec.visual.global_.offheight = rend.image_size
    spec.camera("top").fovy = rend.view_extent
    table = spec.geom("table")
    table.rgba = [*rend.table_rgb, 1.0]
    # Defaults were applied while parsing: set the parsed geoms and, for the object's geoms
    # added later, the default class.
    for geom in (spec.default.geom, table):
        set_contact(geom, phys)
    shaft0 = -2 * hand.tip_half_length - 0.5 * hand.shaft_radius
    shaft1 = shaft0 - hand.shaft_length
    for f, rgb in zip(FINGERS, (rend.index_rgb, rend.thumb_rgb), strict=True):
        spec.material(f"{f}_mat").rgba = [*rgb, 1.0]
        spec.body(f"{f}_base").pos = [0.0, 0.0, hand.height]
        spec.body(f"{f}_tip").mass = hand.mass
        slide = spec.joint(f"{f}_slide")
        slide.range = [0.0, hand.standoff + hand.travel]
        slide.damping = [hand.damping, *slide.damping[1:]]
        for name in LATERAL_JOINTS:
            joint = spec.joint(f"{f}_{name}")
            joint.stiffness = [hand.lateral_stiffness, *joint.stiffness[1:]]
            joint.damping = [hand.lateral_damping, *joint.damping[1:]]
        pad, shaft = spec.geom(f"{f}_pad"), spec.geom(f"{f}_shaft")
        pad.fromto = [-2 * hand.tip_half_length, 0.0, 0.0, 0.0, 0.0, 0.0]
        pad.size = [hand.tip_radius, *pad.size[1:]]
        shaft.fromto = [shaft0, 0.0, 0.0, shaft1, 0.0, 0.0]
        shaft.size = [hand.shaft_radius, *shaft.size[1:]]
        for geom in (pad, shaft):
            set_contact(geom, phys)
        spec.site(f"{f}_sensor").pos = [hand.tip_radius, 0.0, 0.0]
    return spec


def set_contact(geom, phys: PhysicsCfg) -> None:
    """Contact parameters of a geom (or a default class's geom) from the physics config."""
    geom.condim = 1 if phys.friction == 0 else 3
    geom.friction = [phys.friction, 0.005, 0.0001]
    geom.solref = list(phys.solref)
    geom.solimp = [*phys.solimp, 0.5, 2.0]


def compile_model(obj: BuiltObject, cfg: GenerateCfg) -> tuple[mujoco.MjModel, ModelIds]:
    """Compile the model of the hand and one object.

    The object's meshes go in as arrays through `MjSpec` (formatting a 300k-face mesh as MJCF
    text and parsing it back costs seconds): the full-resolution visual mesh, which does not
    collide, and the convex pieces, which collide and are hidden in renders (group 3).
    """
    spec = hand_spec(cfg)
    body = spec.body("object")
    banks = banks_of(cfg)  # textures only for scenes whose effects ask for them
    visual = _add_mesh_geom(spec, body, "object_visual", obj.mesh, (*obj.rgb, 1.0),
                            collide=False, group=0)
    if banks:
        add_banks(spec, banks)
        if "object" in banks:  # texture coordinates, flat normals and a textured material
            mesh = spec.mesh("object_visual_mesh")
            mesh.usertexcoord = planar_texcoords(obj.mesh.vertices).ravel()
            # With texture coordinates MuJoCo shades with the vertex normals as given, which
            # smooth across the rim of a flat top: give each face its own normal instead.
            mesh.usernormal = np.asarray(obj.mesh.face_normals, np.float32).ravel()
            mesh.userfacenormal = np.repeat(np.arange(len(obj.mesh.faces), dtype=np.int32), 3)
            visual.material = next(m.name for m in spec.materials if m.name.startswith("object"))
        if "table" in banks:
            spec.geom("table").material = next(m.name for m in spec.materials
                                               if m.name.startswith("table"))
    for i, piece in enumerate(obj.pieces):
        g = _add_mesh_geom(spec, body, f"piece{i}", piece, (0, 0, 0, 0), collide=True,
                           group=OBJECT_GROUP_COLLISION)
        set_contact(g, cfg.physics)
    model = spec.compile()
    return model, ModelIds.of(model)


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
