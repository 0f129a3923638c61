"""Effects: small callables that corrupt what a configuration yields, run as a list of the
enabled ones.

Four stages, each a list in the `Pipeline`:

- ``grasp``: ``effect(grasp, rng) -> grasp``, per repeat, *before* the physics solve. A grasp
  effect changes the physics, so a configuration with any grasp effect is solved once per repeat.
- ``force``: ``effect(forces, rng) -> forces`` on the measured forces of all repeats of one
  configuration at once, shape (K, 2, 3): repeat, finger (index, thumb), sensor-frame xyz, newtons.
  Without grasp effects, the K repeats share one solve and differ only through these effects.
- ``sensor``: ``effect(series, dt, rng) -> series`` on the 50 Hz force series of a configuration's
  simulated press/hold/release session, shape (T, 2, 3) (see `vistac_sim.recording.session`);
  each press's reading is the series at its peak sample. Only simulated when a sensor effect or
  `--recordings` asks for it.
- ``image``: ``effect(shot, rng) -> shot`` on the render request of a configuration.

A disabled effect is not in the list, so it is never constructed nor called and costs nothing.
Every effect reports its parameters for the manifest through ``params()``.

Each effect module registers itself with `register_effect`: its key in the effects config, its
config dataclass (or, for a one-number effect, its `param`) and the builder of its effects. The
effects config (`EffectsCfg`, one field per registered effect) is assembled from the registry
(`effects_config`), and pipelines run effects in registration order within each stage. A new
effect is one module and one line in `vistac_sim.effects.__init__`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from vistac.config import Config, param


@dataclass(frozen=True)
class Effect:
    """Base of all effects. Subclasses set `name` and `stage` and implement `__call__`."""

    name: ClassVar[str] = "effect"
    stage: ClassVar[str] = "force"

    def params(self) -> dict[str, Any]:
        """The effect's parameters, as written into the manifest."""
        return dataclasses.asdict(self)


@dataclass(frozen=True)
class ConfiguredEffect(Effect):
    """An effect whose parameters are its config dataclass (`cfg`)."""

    cfg: Any

    def params(self) -> dict[str, Any]:
        return dataclasses.asdict(self.cfg)


@dataclass(frozen=True)
class Registered:
    """One registered effect: its config key, the config's type and default, its builder."""

    key: str
    build: Callable[[Any], list[Effect]]
    annotation: Any
    declaration: Any  # the dataclass field of the effects config


_REGISTRY: dict[str, Registered] = {}


def register_effect(key: str, build: Callable[[Any], list[Effect]], cfg: type | None = None,
                    value: Any = None) -> None:
    """Register an effect under its key in the effects config.

    Args:
        key: Field name in the effects config, scene files and presets, e.g. ``finger_pull``.
        build: Turns the field's value (never None) into the effects to run.
        cfg: The effect's config dataclass; the field is ``cfg | None``, off (None) by default.
        value: For an effect set by one number instead: its `param` (type float), e.g. noise.

    Raises:
        ValueError: the key is taken, or neither or both of `cfg` and `value` are given.
    """
    if key in _REGISTRY:
        raise ValueError(f"effect {key!r} is already registered")
    if (cfg is None) == (value is None):
        raise ValueError(f"effect {key!r}: give either cfg or value")
    if cfg is not None:
        doc = (cfg.__doc__ or "").strip().splitlines()[0] if cfg.__doc__ else ""
        _REGISTRY[key] = Registered(key, build, cfg | None, param(None, help=doc))
    else:
        _REGISTRY[key] = Registered(key, build, float, value)


def registered() -> list[Registered]:
    """The registered effects, in registration order (the order they run within a stage)."""
    return list(_REGISTRY.values())


def effects_config() -> type:
    """The effects config dataclass: one field per registered effect, in registration order."""
    fields = [(r.key, r.annotation, r.declaration) for r in _REGISTRY.values()]
    cls = dataclasses.make_dataclass(
        "EffectsCfg", fields, bases=(Config,), frozen=True,
        namespace={"__doc__": "Measurement effects, one field per registered effect.\n\n"
                   "Optional effects are ``X | None`` (None: off, never built); a scene file or "
                   "preset switches any subset on with its parameters "
                   "(see `vistac_sim.effects.presets`)."})
    cls.__module__ = "vistac_sim.effects"  # where it lives (pickled configs find it there)
    return cls


@dataclass
class Pipeline:
    """The enabled effects of a run, grouped by stage, in the order they run."""

    grasp: list[Effect] = field(default_factory=list)
    force: list[Effect] = field(default_factory=list)
    sensor: list[Effect] = field(default_factory=list)
    image: list[Effect] = field(default_factory=list)

    @property
    def changes_physics(self) -> bool:
        """True when some effect needs one physics solve per repeat."""
        return bool(self.grasp)

    @property
    def needs_series(self) -> bool:
        """True when some effect works on the force time series of a session."""
        return bool(self.sensor)

    def all(self) -> list[Effect]:
        return [*self.grasp, *self.force, *self.sensor, *self.image]

    def describe(self) -> list[dict[str, Any]]:
        """One entry per enabled effect: name, stage and parameters (for the manifest)."""
        return [{"name": e.name, "stage": e.stage, "params": e.params()} for e in self.all()]

    def apply_grasp(self, grasp, rng: np.random.Generator):
        for effect in self.grasp:
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

    def apply_image(self, shot, rng: np.random.Generator):
        for effect in self.image:
            shot = effect(shot, rng)
        return shot


def build_pipeline(cfg: Any) -> Pipeline:
    """The effects the config (an `EffectsCfg`) enables, each appended to its stage.

    A builder is only called for a field that is not None; the builder of a one-number effect
    decides itself whether its value switches it on.
    """
    pipeline = Pipeline()
    for r in _REGISTRY.values():
        value = getattr(cfg, r.key)
        if value is not None:
            for effect in r.build(value):
                getattr(pipeline, effect.stage).append(effect)
    return pipeline
