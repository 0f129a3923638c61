"""`LocatorCfg`: how drawn fingers are found in an image, for every step of the locator (the
colour masks of `vistac_learn.data.finger_masks`, the geometry of
`vistac_learn.data.fingertips`, the segmenter's part in `vistac_learn.data.locator`).

Its own module so that the steps import it without importing each other.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from vistac.config import Config, param


@dataclass(frozen=True)
class LocatorCfg(Config):
    """How drawn fingers are found in an image."""

    hue_tol_deg: float = param(35.0, gt=0, le=90, help="widest hue offset of a finger's drawn "
                               "colour from its nominal one")
    min_saturation: float = param(0.3, ge=0, le=1, help="least saturation of a finger pixel")
    min_value: float = param(0.15, ge=0, le=1, help="least brightness of a finger pixel")
    band_deg: float = param(10.0, gt=0, le=90, help="hue band round the drawn colour found in "
                            "the image")
    sat_frac: float = param(0.5, gt=0, le=1, help="least saturation of a finger pixel as a "
                            "fraction of the drawn colour's")
    seed_px: int = param(300, ge=10, help="the most saturated pixels of a finger's hue that "
                         "tell its drawn colour")
    max_area_frac: float = param(0.25, gt=0, le=1, help="a blob of the finger's colour larger "
                                 "than this fraction of the image is not a finger")
    min_area_px: int = param(40, ge=1, help="fewest pixels of a finger that count as found")
    open_px: int = param(7, ge=1, le=31, help="side of the disc that opens the colour mask "
                         "(stripes and specks of the finger's colour thinner than it go; a "
                         "finger's rounded end, wider, stays as it is)")
    min_fill: float = param(0.55, ge=0, le=1, help="least share of its bounding rectangle a "
                            "finger's blob fills (a capsule fills 0.8 or more)")
    ridge_frac: float = param(0.6, gt=0, lt=1, help="centre-line pixels: distance to the "
                              "outline >= ridge_frac * radius")
    facing: float = param(0.85, gt=0, lt=1, help="the tip is the end nearer the other finger "
                          "when its distance is below `facing` times the other end's")
    end_px: float = param(0.0, ge=-2, le=2, help="a finger's end lies this far beyond its "
                          "extreme pixel centre (0: measured on clean renders, where +0.5 put "
                          "the tip 0.4-0.6 px ahead of the simulator's)")
    probe: float = param(1.5, gt=0, help="radius of the look-ahead disc, in finger radii")
    object_tol: float = param(30.0, gt=0, help="RGB distance (0-255) from the table colour "
                              "above which a pixel is object")
    segmenter: Literal["off", "fallback", "check", "always", "refine"] = param(
        "refine", help="the learned segmenter (vistac_learn.data.segmenter) and the colour "
        "fit combined: off (colour fit only); fallback (the learned fit only for a finger the "
        "colour fit misses); check (both run, the learned fit wins where they disagree); "
        "always (the learned fit only); refine (the colour fit inside the segmenter's finger, "
        "kept where it agrees with the learned fit)")
    agree_px: float = param(3.0, gt=0, help="'check' / 'refine': colour and learned tips closer "
                            "than this (and axes within agree_deg) agree; the colour fit is kept")
    agree_deg: float = param(4.0, gt=0, help="'check' / 'refine': largest axis difference that "
                             "agrees")
    refine_px: int = param(1, ge=0, le=10, help="'refine': the colour fit looks for a finger "
                           "within this many pixels of the segmenter's finger")
