"""Effects: small callables that corrupt what a scene yields, run as a list of the enabled ones.

Three stages, each a list in the `Pipeline`:

- ``scene``: ``effect(grasp, rng) -> grasp``, per repeat, *before* the physics solve. A scene
  effect changes the physics, so a configuration with any scene effect is solved once per repeat.
- ``force``: ``effect(forces, rng) -> forces`` on the measured forces of all repeats of one
  configuration at once, shape (K, 2, 3): repeat, finger (index, thumb), sensor-frame xyz, newtons.
  Without scene effects, the K repeats share one solve and differ only through these effects.
- ``image``: ``effect(view, rng) -> view`` on the render request of a configuration.

A disabled effect is not in the list, so it is never constructed nor called and costs nothing.
Every effect reports its parameters for the manifest through ``params()``.
"""

from __future__ import annotations

import dataclasses
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
    image: list[Effect] = field(default_factory=list)

    @property
    def changes_physics(self) -> bool:
        """True when some effect needs one physics solve per repeat."""
        return bool(self.scene)

    def all(self) -> list[Effect]:
        return [*self.scene, *self.force, *self.image]

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


def _enabled_effects(cfg: EffectsCfg) -> list[Effect]:
    effects: list[Effect] = []
    if cfg.noise > 0:
        effects.append(ForceNoise(relative_std=cfg.noise))
    return effects
