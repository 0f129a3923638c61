"""Textures in the scene's model: the texture banks added to an `MjSpec`, and their ids.

Only a scene whose effects ask for textures gets them (the clean scene's model is unchanged):
the object bank when the object-material effect is on, the table bank when the table effect
names texture kinds. Each texture is named ``<bank>_<kind>_<k>``; a configuration picks one per
surface in the visual scene (`vistac_sim.render.shot_render`), so the model is made once per
object and never changed.

The object's mesh has no texture coordinates of its own: it gets a planar projection from
above (u, v = x, -y in metres, object frame), which is what a camera looking down sees of a
label or grain on the object's top; `Surface.repeat` scales it per configuration. It gets flat
normals (one per face) too: with texture coordinates MuJoCo shades with the normals as given.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from vistac_sim.mj import mujoco
from vistac_sim.render import textures

RGB_ROLE = int(mujoco.mjtTextureRole.mjTEXROLE_RGB)


def uses_textures(cfg: Any) -> bool:
    """Whether a generate config's effects put textures of the banks into the scene."""
    effects = cfg.effects
    return effects.object_material is not None or (effects.table is not None
                                                   and bool(effects.table.kinds))


def banks_of(cfg: Any) -> dict[str, dict[str, list[np.ndarray]]]:
    """The texture banks a generate config's effects use: name ("object", "table") -> bank."""
    effects, user = cfg.effects, cfg.render.textures
    out = {}
    if effects.object_material is not None:
        out["object"] = textures.bank("object", user)
    if effects.table is not None and effects.table.kinds:
        out["table"] = textures.bank("table", user)
    return out


def add_banks(spec: mujoco.MjSpec, banks: dict[str, dict[str, list[np.ndarray]]]) -> None:
    """Add every texture of `banks` to `spec`, with one material each (named as the texture)."""
    for which, bank in banks.items():
        for kind, texs in bank.items():
            for k, tex in enumerate(texs):
                name = f"{which}_{kind}_{k}"
                t = spec.add_texture()
                t.name, t.type = name, mujoco.mjtTexture.mjTEXTURE_2D
                t.width, t.height, t.nchannel = tex.shape[1], tex.shape[0], 3
                t.data = np.ascontiguousarray(tex).tobytes()
                m = spec.add_material()
                m.name = name
                names = [""] * len(m.textures)
                names[RGB_ROLE] = name
                m.textures = names


def planar_texcoords(vertices: np.ndarray) -> np.ndarray:
    """(n, 2) texture coordinates of mesh vertices: their (x, -y) in metres, so that a texture
    reads as an image seen from above (OpenGL's texture rows run bottom-up)."""
    uv = np.asarray(vertices, np.float32)[:, :2].copy()
    uv[:, 1] *= -1
    return uv


def texture_ids(model: mujoco.MjModel) -> dict[str, dict[str, list[int]]]:
    """bank -> kind -> the model's texture ids, in variant order."""
    out: dict[str, dict[str, list[int]]] = {}
    for i in range(model.ntex):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_TEXTURE, i) or ""
        parts = name.split("_")
        if len(parts) == 3 and parts[0] in ("object", "table"):
            out.setdefault(parts[0], {}).setdefault(parts[1], []).append(i)
    return out


def pick(ids: dict[str, list[int]], kind: str, u: float) -> int:
    """The texture id a surface's (kind, pick) chooses; -1 for no texture.

    Raises:
        ValueError: a kind the model has no textures of.
    """
    if not kind:
        return -1
    if kind not in ids:
        raise ValueError(f"texture kind {kind!r} is not in the scene's bank ({', '.join(ids)})")
    options = ids[kind]
    return options[min(int(u * len(options)), len(options) - 1)]
