"""The photographs textures are made of, for both packages: which ones, and how one is read.

They are scikit-image's sample images (`skimage.data`: shipped with the package, no download;
CC0 or public domain, see docs/appearance.md). Two users draw from them, each with its own
procedural kinds beside:

- the simulator's texture bank (`vistac_sim.render.textures`): fixed textures, a pure function
  of kind and variant, put into a scene's model; its photographs are `BANK_PHOTOS`, each cut
  as listed;
- the learner's appearance perturbations (`vistac_learn.data.perturb`): a random crop of a
  photograph drawn per perturbed training image; its photographs are `PERTURB_PHOTOS`, grey
  ones among them (tinted when drawn).

The two lists differ, and each stays as it is: the bank's is part of what a seed of a
``photo``-preset dataset looks like, the perturbations' part of the default recipe's training
draws, so changing either changes the datasets or the runs made before.
"""

from __future__ import annotations

import functools

import numpy as np

WHOLE = (0.0, 1.0, 0.0, 1.0)  # a cut (top, bottom, left, right) in fractions: all of it
BANK_PHOTOS: dict[str, tuple[tuple[str, tuple[float, float, float, float]], ...]] = {
    "object": (("coffee", WHOLE), ("chelsea", WHOLE), ("astronaut", WHOLE),
               ("rocket", (0.0, 1.0, 0.2, 0.8))),
    "table": (("gravel", WHOLE), ("brick", WHOLE), ("grass", WHOLE)),
}
PERTURB_PHOTOS: dict[str, tuple[str, ...]] = {
    "table": ("brick", "gravel", "grass", "coffee", "chelsea", "rocket", "camera"),
    "object": ("coffee", "chelsea", "astronaut", "rocket", "immunohistochemistry", "coins",
               "camera", "text", "page"),
}


@functools.cache
def photo(name: str) -> np.ndarray:
    """A sample photograph as (H, W, 3) uint8 RGB (a grey one in every channel), read-only."""
    import skimage.data

    img = np.asarray(getattr(skimage.data, name)())
    if img.ndim == 2:
        img = np.repeat(img[..., None], 3, axis=2)
    out = np.ascontiguousarray(img[..., :3])
    out.setflags(write=False)
    return out


def cut(img: np.ndarray, crop: tuple[float, float, float, float]) -> np.ndarray:
    """The part (top, bottom, left, right, in fractions of the sides) of an image."""
    top, bottom, left, right = crop
    h, w = img.shape[:2]
    return img[int(top * h):int(bottom * h), int(left * w):int(right * w)]
