"""Measurement effects: one small module per effect, each registering itself (`registry`).

The modules are imported here in pipeline order: within a stage, effects run in this order,
which is also the order of the fields of `EffectsCfg` (assembled from the registry) and of the
manifest's effect list. A new effect is a new module below and one line here.
"""

from vistac_sim.effects import (  # noqa: F401, I001  (each module registers its effect)
    noise,
    fts3,
    finger_pull,
    placement_error,
    overlay_error,
    camera_jitter,
    lighting,
    shadows,
    table,
    object_material,
    phone_camera,
    exposure,
    blur,
    sensor_noise,
    jpeg,
    drawn_overlay,
)
from vistac_sim.effects.registry import Effect, Pipeline, build_pipeline, effects_config

EffectsCfg = effects_config()

__all__ = ["Effect", "EffectsCfg", "Pipeline", "build_pipeline"]
