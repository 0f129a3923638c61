"""How grasps are drawn (`GraspCfg`): the spreads of the approach and closing axes.

Its own module so that scene files (`vistac_sim.effects.presets`) may set it as a ``grasp:``
section without importing the whole generation config.
"""

from __future__ import annotations

from dataclasses import dataclass

from vistac.config import Config, param


@dataclass(frozen=True)
class GraspCfg(Config):
    """How contact targets and approach directions are drawn."""

    approach_spread_deg: float = param(
        20.0, ge=0, lt=90, flag="--approach-spread",
        help="max degrees of each finger's axis (its sensor's z) off its target's inward "
        "surface normal")
    closing_spread_deg: float = param(
        20.0, ge=0, lt=90,
        help="max degrees of the hand's closing axis (the push of both fingers) off the index "
        "target's inward normal; the thumb closes along the same axis, where it meets the object "
        "(where the friction cone plus cone_tolerance_deg is narrower, both pushes are drawn "
        "within it: antipodal grasps)")
    max_push_angle_deg: float = param(
        50.0, ge=0, lt=90,
        help="max degrees between the closing axis and the thumb target's surface normal "
        "(further off, a pad slides away along the surface)")
    max_redraws: int = param(60, ge=0, le=100_000,
                             help="per configuration, before the run fails loudly")
