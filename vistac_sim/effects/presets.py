"""Named effect presets and scene files (`--preset NAME`, `--scene FILE`).

A preset or scene file is a partial config: ``effects`` (fields of `EffectsCfg`),
``recording`` (fields of `RecordingCfg`), ``physics`` (fields of `PhysicsCfg`: friction,
time step, the press's phases, contact softness, the checks' tolerances; a value known to bias
labels is refused with its measured bias, `vistac_sim.physics.config.label_bias`) and ``grasp``
(fields of `GraspCfg`: how far approach and closing axes spread off the surface normal). An optional
effect is switched on by a table of its parameters (merged over the preset's, or the defaults)
or by ``true``, and off by ``false`` or ``null``. A scene file may name its base ``preset``;
the `--preset` option wins over it. Example (YAML; TOML works the same with ``[effects.fts3]``
tables)::

    preset: lab
    effects:
      fts3: {hysteresis: 0.03, drift_std: 0.02}
      finger_pull: false
    recording: {hold_s: 1.5}
    physics: {friction: 0.5}
    grasp: {approach_spread_deg: 10, closing_spread_deg: 10}

Unknown keys and values of the wrong type are errors naming the file and the key.
"""

from __future__ import annotations

import tomllib
import warnings
from pathlib import Path
from typing import Any

from vistac.config import apply
from vistac.errors import UserError
from vistac.safe_yaml import load_yaml
from vistac_sim.effects import EffectsCfg
from vistac_sim.generate.grasp_config import GraspCfg
from vistac_sim.physics.config import BiasedPhysicsWarning, PhysicsCfg, label_bias
from vistac_sim.recording.config import RecordingCfg

# What each preset switches on, over the defaults of each effect's config.
PRESETS: dict[str, dict[str, Any]] = {
    # nothing but --noise
    "clean": {},
    # what the study's set-up suffered: the FTS-3 as on its datasheet, a hand-pressed finger that
    # is pulled sideways and lands off its target, fingers drawn by hand into the photo, shadows
    "lab": {"effects": {
        "fts3": {"nonlinearity": 0.025, "hysteresis": 0.02, "drift_std": 0.01,
                 "offset_std": 0.005, "sample_noise": 0.002},
        "finger_pull": {"mean": 0.15, "spread": 0.05, "config_spread": 0.08},
        "placement_error": {"position_std": 0.001, "angle_std_deg": 3.0},
        "overlay_error": True,
        "shadows": True,
    }},
    # more of everything, and the visual effects the study's fixed set-up did not have
    "harsh": {"effects": {
        # bias and noise stay below ~0.1 N at rest, so a press/rest split still works
        "fts3": {"nonlinearity": 0.05, "hysteresis": 0.04, "drift_std": 0.015,
                 "offset_std": 0.01, "sample_noise": 0.004},
        "finger_pull": {"mean": 0.3, "spread": 0.15, "config_spread": 0.15},
        "placement_error": {"position_std": 0.0025, "angle_std_deg": 8.0},
        "overlay_error": {"offset_std": 0.004, "rotation_std_deg": 6.0},
        "camera_jitter": True,
        "lighting": True,
        "shadows": True,
        "table": True,
    }},
    # appearance only, like the study's smartphone photographs: textured objects on a textured
    # table, a coloured key light with soft shadows, a slightly tilted perspective phone camera
    # with its exposure, white balance, blur, noise and JPEG, and fingers drawn by hand. Nothing
    # label-side: the same seed gives the same presses and forces as `clean`.
    "photo": {"effects": {
        "object_material": True,
        "table": {"rgb_std": 0.08, "texture": 0.0, "kinds": ["wood", "cloth", "paper", "photo"]},
        "lighting": {"elevation_deg": [40.0, 85.0], "intensity": [0.45, 0.75],
                     "ambient": [0.3, 0.5], "specular": 0.3, "temperature_k": [3000.0, 7500.0]},
        "shadows": {"map_size": 256, "softness": 0.02, "probability": 0.2},
        "phone_camera": True,
        "exposure": True,
        "blur": True,
        "sensor_noise": {"read": [0.5, 2.0], "shot": [0.0, 0.06]},
        "jpeg": True,
        "drawn_overlay": True,
    }},
}
SCENE_SUFFIXES = (".yaml", ".yml", ".toml")
MAX_SCENE_BYTES = 1 << 20
"""A scene file is a few settings: anything larger is a mistake (or an attack), refused unread."""
# The parts of the generate config a scene file may set, with their config classes.
SECTIONS = {"effects": EffectsCfg, "recording": RecordingCfg, "physics": PhysicsCfg,
            "grasp": GraspCfg}


def resolve(preset: str | None = None, scene: str | Path | None = None,
            noise: float | None = None) -> tuple[EffectsCfg, RecordingCfg]:
    """The effects and session config of a preset, a scene file applied over it, and `--noise`
    (`resolve_sections` without the physics)."""
    sections = resolve_sections(preset, scene, noise)
    return sections["effects"], sections["recording"]


def resolve_sections(preset: str | None = None, scene: str | Path | None = None,
                     noise: float | None = None) -> dict[str, Any]:
    """Each section of `SECTIONS` from a preset, a scene file applied over it, and `--noise`.

    A ``physics`` table that sets a value known to bias labels (`label_bias`) is refused, with
    the bias measured.

    Args:
        preset: preset name; None takes the scene file's ``preset`` or else ``clean``.
        scene: YAML (.yaml, .yml) or TOML (.toml) scene file, or None.
        noise: `--noise` when given (wins over the scene file's ``effects.noise``).

    Raises:
        UserError: an unknown preset, an unreadable file, an unknown key or a bad value.
    """
    data = load_scene(scene) if scene is not None else {}
    source = str(scene) if scene is not None else "scene"
    name = preset or data.pop("preset", None) or "clean"
    data.pop("preset", None)
    if not isinstance(name, str) or name not in PRESETS:
        raise UserError(f"{source}: unknown preset {name!r} (known: {', '.join(PRESETS)})")
    sections = {key: cls() for key, cls in SECTIONS.items()}
    for where, layer in ((f"preset {name}", PRESETS[name]), (source, data)):
        for key, value in layer.items():
            if key not in sections:
                raise UserError(f"{where}: unknown key {key!r} (known: {', '.join(sections)})")
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", BiasedPhysicsWarning)  # refused just below
                sections[key] = apply(sections[key], value, where, prefix=key)
    biased = label_bias(sections["physics"])
    if biased:
        raise UserError(f"{source}: physics.{biased[0][0]}: {biased[0][1]}")
    if noise is not None:
        sections["effects"] = apply(sections["effects"], {"noise": noise},
                                    labels={"noise": "--noise"})
    return sections


def load_scene(path: str | Path) -> dict[str, Any]:
    """Read a scene file into a dict (top level checked against the known sections).

    YAML is read by `vistac.safe_yaml.load_yaml` (alias expansion bounded, ``1e-2`` a number).

    Raises:
        UserError: missing file, unknown suffix, a file too large, a parse error, an alias
            bomb, or a non-table top level.
    """
    path = Path(path)
    if not path.is_file():
        raise UserError(f"{path}: no such scene file")
    suffix = path.suffix.lower()
    if suffix not in SCENE_SUFFIXES:
        raise UserError(f"{path}: scene files are YAML (.yaml, .yml) or TOML (.toml)")
    if path.stat().st_size > MAX_SCENE_BYTES:
        raise UserError(f"{path}: {path.stat().st_size} bytes; a scene file holds at most "
                        f"{MAX_SCENE_BYTES} (a few settings)")
    try:
        text = path.read_text()
        if suffix == ".toml":
            data = tomllib.loads(text)
        else:
            data = load_yaml(text, str(path))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise UserError(f"{path}: cannot parse: {' '.join(str(exc).split())}") from None
    except RecursionError:
        raise UserError(f"{path}: lists or tables nested too deeply") from None
    data = {} if data is None else data
    if not isinstance(data, dict):
        raise UserError(f"{path}: the top level must be a table of settings")
    unknown = set(data) - {"preset", *SECTIONS}
    if unknown:
        raise UserError(f"{path}: unknown key {sorted(unknown)[0]!r} (known: preset, "
                        f"{', '.join(SECTIONS)})")
    return dict(data)
