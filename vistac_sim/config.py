"""The generation config: a tree of small dataclasses, every knob with its default.

The whole tree is written into `manifest.json` (``to_dict``) so that a dataset states exactly how
it was made, and `--resume` can refuse to continue a run made with other settings.
"""

from __future__ import annotations

import dataclasses
import types
import typing
from dataclasses import dataclass, field
from typing import Any, Literal

PROCEDURAL_FAMILIES = (
    "cylinder",
    "box",
    "prism",
    "rounded_rect",
    "L",
    "U",
    "star",
    "crescent",
)
CONCAVE_FAMILIES = ("L", "U", "star", "crescent")


@dataclass
class HandCfg:
    """Geometry and drive of the two fingertips (sizes in metres, forces in newtons).

    The RH8D is a human-scale hand; the distal phalanx with its FTS-3 fingertip is modelled as a
    capsule of 9.5 mm radius (19 mm wide, the width of an adult distal phalanx) whose rounded end
    carries the sensor pad, behind it a shaft standing in for the middle phalanx. These sizes are
    approximations of a human-scale fingertip, not measurements of Seed Robotics CAD.
    """

    tip_radius: float = 0.0095
    tip_half_length: float = 0.008  # half length of the tip capsule's straight part
    shaft_radius: float = 0.0085
    shaft_length: float = 0.045  # drawn and collided middle phalanx behind the tip
    height: float = 0.012  # fingertip axis above the table top
    mass: float = 0.03  # kg, the moving fingertip body
    damping: float = 4.0  # N s/m on the slide joint, so the press settles quickly
    press_force: float = 2.0  # N, drive force along the approach direction
    standoff: float = 0.003  # m, gap between tip and target before the press
    travel: float = 0.012  # m, furthest the tip may move before "no contact"


@dataclass
class ObjectsCfg:
    """Which objects lie on the table."""

    families: tuple[str, ...] = PROCEDURAL_FAMILIES
    paths: tuple[str, ...] = ()  # user meshes (files or folders); replaces families when given
    n_objects: int = 32  # size of the procedural object library drawn from the seed
    footprint: tuple[float, float] = (0.035, 0.075)  # m, longest side of the top-view outline
    height: tuple[float, float] = (0.03, 0.05)  # m, extrusion height of procedural objects
    min_wall: float = 0.001  # m, thinnest wall a procedural outline may have
    strict: bool = False  # a bad mesh in a folder aborts instead of being skipped


@dataclass
class GraspCfg:
    """How contact targets and approach directions are drawn."""

    approach_spread_deg: float = 20.0  # max angle of the approach off the inward surface normal
    min_opposition_deg: float = 90.0  # min angle between index and thumb approach directions
    max_redraws: int = 60  # per configuration, before the run fails loudly


@dataclass
class PhysicsCfg:
    """MuJoCo settings of the press."""

    friction: float = 0.6  # sliding friction coefficient; 0 makes contacts frictionless
    timestep: float = 0.002
    settle_steps: int = 150  # 0.3 s: forces agree with 1000 steps to ~1e-9 N (median)
    solref: tuple[float, float] = (0.004, 1.0)
    solimp: tuple[float, float, float] = (0.99, 0.999, 0.0005)
    max_penetration: float = 0.001  # m; deeper contacts are rejected
    max_speed: float = 1e-3  # m/s; a tip still moving after settling is rejected
    cone_tolerance_deg: float = 3.0  # slack of the check "force within the friction cone"


@dataclass
class RenderCfg:
    """The orthographic top view."""

    image_size: int = 227
    view_extent: float = 0.16  # m of table across the image
    table_rgb: tuple[float, float, float] = (0.81, 0.81, 0.81)
    index_rgb: tuple[float, float, float] = (0.0, 0.85, 0.0)
    thumb_rgb: tuple[float, float, float] = (0.9, 0.0, 0.0)


@dataclass
class Fts3Cfg:
    """FTS-3 fingertip sensor model, applied along the 50 Hz force series (per axis, newtons).

    Defaults are the datasheet values of the thesis (range 10 N, resolution 1 mN, non-linearity
    2.5 %, hysteresis 2 %); drift, offset and sample noise are not on the datasheet and are our
    estimates. A part whose parameter is 0 is not built.
    """

    full_scale: float = 10.0  # N per axis; readings saturate at +-full_scale (0: no saturation)
    resolution: float = 0.001  # N, quantisation step of the readings (0: off)
    nonlinearity: float = 0.025  # max deviation from linear, fraction of full scale (0: off)
    hysteresis: float = 0.02  # loading/unloading loop width, fraction of |input| (0: off)
    hysteresis_smoothing: float = 0.05  # N of input travel over which a branch switch completes
    drift_std: float = 0.01  # N, stationary std of the slow bias drift (0: off)
    drift_tau: float = 30.0  # s, correlation time of the drift
    offset_std: float = 0.005  # N, std of the zero offset left by calibration (0: off)
    sample_noise: float = 0.002  # N, white noise std per sample (0: off)


@dataclass
class FingerPullCfg:
    """Sideways (sensor y) force of a finger that is pulled or slides while pressed.

    The added F_y is ``fraction * |F_z|`` with fraction = mean + per-configuration draw +
    per-press draw (Gaussian), in each listed finger's own sensor frame.
    """

    mean: float = 0.15  # systematic part, fraction of |F_z| (+y as seen in the study)
    spread: float = 0.05  # per-press std of the fraction
    config_spread: float = 0.05  # per-configuration std of the fraction (shared by its presses)
    fingers: tuple[str, ...] = ("index", "thumb")


@dataclass
class PlacementErrorCfg:
    """The finger lands a little off its target on each repeat (one physics solve per repeat)."""

    position_std: float = 0.001  # m, std of the target shift per axis (world xy)
    angle_std_deg: float = 3.0  # std of the approach direction's rotation


@dataclass
class OverlayErrorCfg:
    """The drawn fingers are offset and rotated from where the fingers really were (image only).

    Per configuration and finger: a shift in the table plane and a rotation about the fingertip,
    each a fixed bias plus a Gaussian draw. The physics and force labels are untouched; the
    stored finger boxes follow the drawn fingers.
    """

    offset_std: float = 0.002  # m, std of the shift per world axis
    rotation_std_deg: float = 3.0  # std of the rotation about the fingertip
    offset: tuple[float, float] = (0.0, 0.0)  # m, fixed shift (world x, y) added to the draw
    rotation_deg: float = 0.0  # fixed rotation (counter-clockwise seen from above) added


@dataclass
class LightingCfg:
    """A directional key light of random direction and intensity instead of the plain headlight.

    The headlight keeps only its ambient part; the key light adds diffuse and specular light.
    """

    elevation_deg: tuple[float, float] = (35.0, 80.0)  # uniform range above the table plane
    azimuth_deg: tuple[float, float] = (0.0, 360.0)  # uniform range, from world +x towards +y
    intensity: tuple[float, float] = (0.4, 0.8)  # uniform range of the key light's diffuse
    ambient: tuple[float, float] = (0.3, 0.55)  # uniform range of the ambient light
    specular: float = 0.2  # key light's specular


@dataclass
class ShadowsCfg:
    """Shadow mapping of the key light (the slower render path; only scenes that ask pay).

    Without the lighting effect a fixed key light of this direction casts the shadows.
    """

    map_size: int = 2048  # texels of the shadow map (MuJoCo's `shadowsize`)
    elevation_deg: float = 55.0  # direction of the fixed key light (no lighting effect)
    azimuth_deg: float = 30.0


@dataclass
class TableCfg:
    """Table colour and texture per configuration."""

    rgb_std: float = 0.05  # std of the per-channel change of the table colour
    texture: float = 0.04  # relative std of the table's brightness pattern (0: plain)
    texture_scale: float = 0.004  # m, grain size of the pattern
    texture_octaves: int = 3  # layers of halving grain size


@dataclass
class CameraJitterCfg:
    """Small changes of the top camera per configuration: shift, scale, tilt and roll."""

    shift_std: float = 0.003  # m, std of the view centre's shift per world axis
    scale_std: float = 0.02  # relative std of the scale (pixels per metre)
    tilt_std_deg: float = 1.0  # std of the view axis's lean off vertical, per horizontal axis
    roll_std_deg: float = 1.0  # std of the rotation about the view axis


@dataclass
class EffectsCfg:
    """Measurement effects. Each enabled effect becomes one callable in the pipeline.

    Optional effects are ``X | None`` (None: off, never built); a scene file or preset switches
    any subset on with its parameters (see `vistac_sim.presets`).
    """

    noise: float = 0.0  # relative std of the per-press force noise (0 disables the effect)
    fts3: Fts3Cfg | None = None
    finger_pull: FingerPullCfg | None = None
    placement_error: PlacementErrorCfg | None = None
    overlay_error: OverlayErrorCfg | None = None
    camera_jitter: CameraJitterCfg | None = None
    lighting: LightingCfg | None = None
    shadows: ShadowsCfg | None = None
    table: TableCfg | None = None


@dataclass
class RecordingCfg:
    """The simulated press/hold/release session of a configuration (RH8D/FTS-3 CSV stream).

    Each press: a rise (smooth start, a sharp peak at the solved force), a relaxation of
    `overshoot` towards the hold level, the hold, a release, then rest. Durations vary by
    `timing_jitter` (relative, uniform) from press to press.
    """

    write: bool = False  # write recordings/NNNNNN.csv (`--recordings`)
    rate_hz: float = 50.0
    rest_s: float = 1.0  # before the first press and after each press
    rise_s: float = 0.4
    hold_s: float = 1.0
    release_s: float = 0.4
    overshoot: float = 0.08  # fraction the force relaxes after the peak
    relax_s: float = 0.1  # time constant of that relaxation
    timing_jitter: float = 0.2


@dataclass
class SplitCfg:
    """Assignment of whole configurations (or whole objects) to train / val / test."""

    by: Literal["config", "object"] = "config"
    fractions: tuple[float, float, float] = (0.7, 0.15, 0.15)


@dataclass
class GenerateCfg:
    """Everything `vistac generate` needs. Sub-trees default to the values above."""

    n: int = 200
    seed: int = 0
    repeats: int = 6
    chunk_size: int = 50  # configurations per shard (unit of work, resume and determinism)
    hand: HandCfg = field(default_factory=HandCfg)
    objects: ObjectsCfg = field(default_factory=ObjectsCfg)
    grasp: GraspCfg = field(default_factory=GraspCfg)
    physics: PhysicsCfg = field(default_factory=PhysicsCfg)
    render: RenderCfg = field(default_factory=RenderCfg)
    effects: EffectsCfg = field(default_factory=EffectsCfg)
    recording: RecordingCfg = field(default_factory=RecordingCfg)
    split: SplitCfg = field(default_factory=SplitCfg)

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-able dict of the whole tree (tuples become lists)."""
        return _jsonable(dataclasses.asdict(self))


def _jsonable(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: _jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_jsonable(v) for v in value]
    return value


def from_dict(cls: type, data: dict[str, Any]):
    """Build dataclass `cls` from a (possibly partial) nested dict; unknown keys are errors."""
    from vistac_sim.errors import UserError

    names = {f.name: f for f in dataclasses.fields(cls)}
    kwargs = {}
    for key, value in data.items():
        if key not in names:
            raise UserError(f"unknown config key {key!r} for {cls.__name__}")
        f = names[key]
        default = getattr(cls(), key) if f.default is dataclasses.MISSING else f.default
        optional = optional_dataclass(cls, key)
        if optional is not None:  # `X | None`: None (off) or a partial dict of X
            kwargs[key] = None if value is None else from_dict(optional, value)
        elif dataclasses.is_dataclass(default):
            kwargs[key] = from_dict(type(default), value)
        elif isinstance(default, tuple):
            kwargs[key] = tuple(value)
        else:
            kwargs[key] = value
    return cls(**kwargs)


def optional_dataclass(cls: type, name: str) -> type | None:
    """The dataclass X of a field annotated ``X | None`` (an optional effect), else None."""
    hint = typing.get_type_hints(cls).get(name)
    if typing.get_origin(hint) not in (types.UnionType, typing.Union):
        return None
    args = [a for a in typing.get_args(hint) if a is not type(None)]
    return args[0] if len(args) == 1 and dataclasses.is_dataclass(args[0]) else None
