"""The fingertip locator's entry point: the colour fit (`vistac_learn.data.fingertips`) and the
learned segmenter (`vistac_learn.data.segmenter`) combined as `LocatorCfg.segmenter` says.

- ``refine`` (default): the segmenter picks each finger's blob, the colour fit draws its
  sub-pixel outline inside it (`refined_fingertips`), kept where it agrees with the learned fit
  (`agree`); a flat render (`flat_render`) is read by the colour fit alone, which is what
  ``refine`` gives there;
- ``fallback``: the learned fit only for a finger the colour fit misses;
- ``check``: both over the whole image, the learned fit where they disagree;
- ``always``: the learned fit; ``off``: the colour fit.
"""

from __future__ import annotations

import cv2
import numpy as np

from vistac.dataset.schema import TABLE_RGB
from vistac.errors import UserError
from vistac_learn.data.finger_masks import explained_finger_masks
from vistac_learn.data.fingertips import Fingertip, LocatorCfg, colour_fingertips, fit_fingers

FLAT_COLOURS = 8  # a flat render has its four colours (table, object, two overlays)


def flat_render(rgb: np.ndarray) -> bool:
    """Whether an image is a flat-colour render (at most `FLAT_COLOURS` distinct colours, no
    shading, texture, blur or noise): there the colour fit is exact, and ``refine`` gives what
    it gives (tested), so the segmenter is not run."""
    packed = (rgb[..., 0].astype(np.uint32) << 16) | (rgb[..., 1].astype(np.uint32) << 8) | \
        rgb[..., 2]
    return len(np.unique(packed)) <= FLAT_COLOURS


def locate_fingertips(rgb: np.ndarray, colours: dict[str, tuple],
                      cfg: LocatorCfg = LocatorCfg()) -> dict[str, Fingertip]:
    """Every finger of `colours` located in an (H, W, 3) uint8 RGB image: by its colour
    (`colour_fingertips`), by the learned segmenter (`learned_fingertips`), or both, as
    `LocatorCfg.segmenter` says (`combine`); a flat render (`flat_render`) by its colour
    alone under ``refine``."""
    if rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.dtype != np.uint8:
        raise UserError(f"expected an (H, W, 3) uint8 RGB image, got {rgb.shape} {rgb.dtype}")
    mode = cfg.segmenter
    if mode == "refine" and flat_render(rgb):
        return colour_fingertips(rgb, colours, cfg)  # what 'refine' gives there, 6x cheaper
    if mode == "refine":
        learned, masks = learned_fit(rgb, colours, cfg)
        return combine(None, learned, cfg, refined_fingertips(rgb, colours, cfg, masks))
    colour = colour_fingertips(rgb, colours, cfg) if mode != "always" else None
    if mode == "off" or (mode == "fallback" and all(t.ok for t in colour.values())):
        return colour
    return combine(colour, learned_fingertips(rgb, colours, cfg), cfg)


def agree(a: Fingertip, b: Fingertip, cfg: LocatorCfg) -> bool:
    """Whether two found fingertips agree: tips within `agree_px`, axes within `agree_deg`."""
    cos = float(np.clip(a.axis @ b.axis, -1.0, 1.0))
    return bool(np.hypot(*(a.tip - b.tip)) <= cfg.agree_px
                and np.degrees(np.arccos(cos)) <= cfg.agree_deg)


def combine(colour: dict[str, Fingertip] | None, learned: dict[str, Fingertip],
            cfg: LocatorCfg, refined: dict[str, Fingertip] | None = None
            ) -> dict[str, Fingertip]:
    """Per finger, the colour fit or the learned one as `LocatorCfg.segmenter` says.

    ``fallback``: the colour fit where found, else the learned one. ``check``: the colour fit
    where both are found and agree (`agree`), the learned fit where they disagree or only it
    is found, the colour fit where only it is found. ``always``: the learned fit.
    ``refine``: the colour fit inside the segmenter's finger (`refined`, from
    `refined_fingertips`) where it agrees with the learned fit, the learned fit where they
    disagree or only it is found, the refined (there: unrestricted) colour fit where only it
    is found. A finger found by neither says both reasons.
    """
    if cfg.segmenter == "refine":
        if refined is None:
            raise ValueError("combine: 'refine' needs the refined colour fit")
        colour = refined
    out = {}
    for f, got in learned.items():
        mine = colour[f] if colour is not None else None
        if cfg.segmenter == "always" or mine is None:
            out[f] = got
        elif not got.ok:
            out[f] = mine if mine.ok else Fingertip.missing(f"{mine.reason}; {got.reason}")
        elif not mine.ok:
            out[f] = got
        elif cfg.segmenter == "fallback":
            out[f] = mine
        else:
            out[f] = mine if agree(mine, got, cfg) else got
    return out


def learned_fingertips(rgb: np.ndarray, colours: dict[str, tuple], cfg: LocatorCfg,
                       model=None) -> dict[str, Fingertip]:
    """The fingers located on the learned segmenter's labels (drawn in the flat palette of a
    clean render, `segmenter.palette_image`) by the colour fit; a failure's reason starts with
    ``segmenter:``."""
    return learned_fit(rgb, colours, cfg, model)[0]


def learned_fit(rgb: np.ndarray, colours: dict[str, tuple], cfg: LocatorCfg, model=None
                ) -> tuple[dict[str, Fingertip], dict[str, np.ndarray]]:
    """`learned_fingertips` and each finger's mask as the segmenter sees it (its largest
    finger-like blob, holes filled; empty where none)."""
    from vistac_learn.data.segmenter import palette_image, segment_image

    flat = palette_image(segment_image(rgb, model), colours, TABLE_RGB)
    masks, why = explained_finger_masks(flat, colours, cfg)
    found = fit_fingers(flat, masks, why, cfg)
    return ({f: t if t.ok else Fingertip.missing(f"segmenter: {t.reason}")
             for f, t in found.items()}, masks)


def refined_fingertips(rgb: np.ndarray, colours: dict[str, tuple], cfg: LocatorCfg,
                       learned_masks: dict[str, np.ndarray]) -> dict[str, Fingertip]:
    """The colour fit inside the segmenter's fingers: each finger's colour looked for only
    within `LocatorCfg.refine_px` of its learned mask (the whole image where that is empty),
    so the segmenter picks the blob and the colour fit draws its sub-pixel outline."""
    return colour_fingertips(rgb, colours, cfg, refine_regions(learned_masks, cfg))


def refine_regions(learned_masks: dict[str, np.ndarray], cfg: LocatorCfg
                   ) -> dict[str, np.ndarray]:
    """Where the colour fit looks under ``refine``: each learned finger mask grown by
    `LocatorCfg.refine_px` (fingers the segmenter did not find are left out: the whole image)."""
    k = 2 * cfg.refine_px + 1
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k))
    return {f: cv2.dilate(m.astype(np.uint8), kernel) > 0
            for f, m in learned_masks.items() if m.any()}
