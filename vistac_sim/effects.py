"""Effects: small callables that corrupt what a scene yields, run as a list of the enabled ones.

Three stages, each a list in the `Pipeline`:

- ``scene``: ``effect(grasp, rng) -> grasp``, per repeat, *before* the physics solve. A scene
  effect changes the physics, so a configuration with any scene effect is solved once per repeat.
- ``force``: ``effect(forces, rng) -> forces`` on the measured forces of all repeats of one
  configuration at once, shape (K, 2, 3): repeat, finger (index, thumb), sensor-frame xyz, newtons.
  Without scene effects, the K repeats share one solve and differ only through these effects.
- ``sensor``: ``effect(series, dt, rng) -> series`` on the 50 Hz force series of a configuration's
  simulated press/hold/release session, shape (T, 2, 3) (see `vistac_sim.session`); each press's
  reading is the series at its peak sample. Only simulated when a sensor effect or `--recordings`
  asks for it.
- ``image``: ``effect(view, rng) -> view`` on the render request of a configuration.

A disabled effect is not in the list, so it is never constructed nor called and costs nothing.
Every effect reports its parameters for the manifest through ``params()``. `EFFECT_BUILDERS`
maps each field of `EffectsCfg` to the function that builds its effects from the field's value;
a new effect adds its config field and one line there.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from vistac_sim.config import EffectsCfg


@dataclass(frozen=True)
class Effect:
    """Base of all effects. Subclasses set `name` and `stage` and implement `__call__`."""

    name: ClassVar[str] = "effect"
    stage: ClassVar[str] = "force"

    def params(self) -> dict[str, Any]:
        """The effect's parameters, as written into the manifest."""
        return dataclasses.asdict(self)


@dataclass(frozen=True)
class ForceNoise(Effect):
    """Per-press Gaussian measurement noise, relative to the force magnitude.

    Each component of each finger's force gets independent noise with standard deviation
    ``relative_std * |F|`` (the noise-free magnitude of that finger's force in that repeat).
    """

    name: ClassVar[str] = "force_noise"
    stage: ClassVar[str] = "force"
    relative_std: float = 0.05

    def __call__(self, forces: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        scale = self.relative_std * np.linalg.norm(forces, axis=-1, keepdims=True)
        return forces + scale * rng.standard_normal(forces.shape)


@dataclass
class Pipeline:
    """The enabled effects of a scene, grouped by stage, in the order they run."""

    scene: list[Effect] = field(default_factory=list)
    force: list[Effect] = field(default_factory=list)
    sensor: list[Effect] = field(default_factory=list)
    image: list[Effect] = field(default_factory=list)

    @property
    def changes_physics(self) -> bool:
        """True when some effect needs one physics solve per repeat."""
        return bool(self.scene)

    @property
    def needs_series(self) -> bool:
        """True when some effect works on the force time series of a session."""
        return bool(self.sensor)

    def all(self) -> list[Effect]:
        return [*self.scene, *self.force, *self.sensor, *self.image]

    def describe(self) -> list[dict[str, Any]]:
        """One entry per enabled effect: name, stage and parameters (for the manifest)."""
        return [{"name": e.name, "stage": e.stage, "params": e.params()} for e in self.all()]

    def apply_scene(self, grasp, rng: np.random.Generator):
        for effect in self.scene:
            grasp = effect(grasp, rng)
        return grasp

    def apply_force(self, forces: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        for effect in self.force:
            forces = effect(forces, rng)
        return forces

    def apply_sensor(self, series: np.ndarray, dt: float, rng: np.random.Generator) -> np.ndarray:
        for effect in self.sensor:
            series = effect(series, dt, rng)
        return series

    def apply_image(self, view, rng: np.random.Generator):
        for effect in self.image:
            view = effect(view, rng)
        return view


def build_pipeline(cfg: EffectsCfg) -> Pipeline:
    """The list of effects the config enables, each appended to its stage."""
    pipeline = Pipeline()
    for effect in _enabled_effects(cfg):
        getattr(pipeline, effect.stage).append(effect)
    return pipeline


def _noise_effects(noise: float) -> list[Effect]:
    return [ForceNoise(relative_std=noise)] if noise > 0 else []


def _fts3_effects(cfg) -> list[Effect]:
    from vistac_sim.sensor_model import fts3_effects

    return fts3_effects(cfg)


def _finger_pull(cfg) -> list[Effect]:
    from vistac_sim.hand_effects import FingerPull

    return [FingerPull.from_cfg(cfg)]


def _placement_error(cfg) -> list[Effect]:
    from vistac_sim.hand_effects import PlacementError

    return [PlacementError.from_cfg(cfg)]


def _image_effect(key: str) -> Callable[[Any], list[Effect]]:
    def build(cfg) -> list[Effect]:
        from vistac_sim.image_effects import image_effect

        return [image_effect(key, cfg)]

    return build


# EffectsCfg field -> builder of its effects. A builder is only called for a field that is not
# None; effects run in the order of the EffectsCfg fields (within each stage).
EFFECT_BUILDERS: dict[str, Callable[[Any], list[Effect]]] = {
    "noise": _noise_effects,
    "fts3": _fts3_effects,
    "finger_pull": _finger_pull,
    "placement_error": _placement_error,
    **{key: _image_effect(key) for key in ("overlay_error", "camera_jitter", "lighting",
                                            "shadows", "table")},
}


def _enabled_effects(cfg: EffectsCfg) -> list[Effect]:
    effects: list[Effect] = []
    for f in dataclasses.fields(cfg):
        value = getattr(cfg, f.name)
        if value is None:
            continue
        if f.name not in EFFECT_BUILDERS:
            raise RuntimeError(f"EffectsCfg.{f.name} has no builder in EFFECT_BUILDERS")
        effects += EFFECT_BUILDERS[f.name](value)
    return effects
