"""A small learned segmenter of top views: table, object, index overlay, thumb overlay per pixel.

The fingertip locator's front end for photo-like images (`vistac_learn.data.fingertips`): the
net labels each pixel with the generator's mask codes (0 table, 1 object, 2 index overlay,
3 thumb overlay; `perturb.TABLE`, `perturb.OBJECT`, `perturb.FINGER_LABEL`), the labels are
drawn in the flat palette of a clean render (`palette_image`), and the analytic locator runs on
that, so its sub-pixel finger fit is reused unchanged.

The net (`TinyUNet`) is a five-level U-Net with full-resolution output (`DEFAULT_WIDTHS`, about
230 k parameters), trained on generator images with exact labels (clean renders, the same
renders perturbed by `vistac_learn.data.perturb`, and ``--preset photo --masks`` renders of
three seeds: `vistac_learn.train.segmenter`, run by ``benchmarks/train_segmenter.py``). Its
weights ship with the package (`WEIGHTS`) and load with ``torch.load(weights_only=True)``.
"""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np
import torch
from torch import nn

from vistac.errors import UserError
from vistac_learn.data.perturb import FINGER_LABEL, OBJECT, TABLE

WEIGHTS = Path(__file__).resolve().parent / "segmenter_weights.pt"
"""The trained weights shipped with the package."""
FORMAT = "vistac-segmenter-1"
"""What a weights file says it is (its ``format`` entry)."""
CLASSES = 4
DEFAULT_WIDTHS = (8, 16, 32, 48, 64)
"""Channels of the shipped net's levels (five: 1/16 resolution at the bottom, context enough to
tell a finger from a table or object of its colour; about 25 CPU ms per 227 px image)."""
NATIVE_PX = 227
"""Side of the images the net was trained on (the generator's default): larger or smaller
images are resized to it for the net, and its labels back (fingers of the size it learned)."""
OBJECT_RGB = (60, 60, 140)  # an object colour far from the table and from both overlays


def _block(cin: int, cout: int) -> nn.Sequential:
    return nn.Sequential(nn.Conv2d(cin, cout, 3, padding=1, bias=False), nn.BatchNorm2d(cout),
                         nn.ReLU(inplace=True),
                         nn.Conv2d(cout, cout, 3, padding=1, bias=False), nn.BatchNorm2d(cout),
                         nn.ReLU(inplace=True))


class TinyUNet(nn.Module):
    """A U-Net with `len(widths)` levels (each halving the resolution) and full-resolution
    logits of `CLASSES` classes; any image size (padded to a multiple of 2^(levels-1))."""

    def __init__(self, widths: tuple[int, ...] = DEFAULT_WIDTHS):
        super().__init__()
        self.widths = tuple(int(w) for w in widths)
        self.down = nn.ModuleList()
        cin = 3
        for w in self.widths:
            self.down.append(_block(cin, w))
            cin = w
        self.up = nn.ModuleList(_block(self.widths[i + 1] + self.widths[i], self.widths[i])
                                for i in reversed(range(len(self.widths) - 1)))
        self.head = nn.Conv2d(self.widths[0], CLASSES, 1)
        self.pool = nn.MaxPool2d(2)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """(B, 3, H, W) float RGB in [0, 1] to (B, CLASSES, H, W) logits."""
        h, w = x.shape[-2:]
        m = 2 ** (len(self.widths) - 1)
        ph, pw = (-h) % m, (-w) % m
        x = nn.functional.pad(x - 0.5, (0, pw, 0, ph), mode="replicate")
        skips = []
        for i, block in enumerate(self.down):
            x = block(x if i == 0 else self.pool(x))
            skips.append(x)
        for block, skip in zip(self.up, reversed(skips[:-1]), strict=True):
            x = nn.functional.interpolate(x, size=skip.shape[-2:], mode="bilinear",
                                          align_corners=False)
            x = block(torch.cat([x, skip], 1))
        return self.head(x)[..., :h, :w]


def save_weights(model: TinyUNet, path: Path, meta: dict) -> None:
    """Write a model's weights, its widths and `meta` (str / number values) to `path`."""
    torch.save({"format": FORMAT, "widths": list(model.widths), "meta": dict(meta),
                "state": {k: v.detach().cpu() for k, v in model.state_dict().items()}}, path)


def load_weights(path: str | Path) -> TinyUNet:
    """A segmenter from a weights file (`save_weights`), in eval mode.

    Raises:
        UserError: The file is missing, unreadable or not a segmenter's weights.
    """
    path = Path(path)
    if not path.is_file():
        raise UserError(f"{path}: segmenter weights missing (reinstall vistac, or retrain them "
                        "with benchmarks/train_segmenter.py)")
    try:
        blob = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:  # pickle, zip and torch errors have no common base
        raise UserError(f"{path}: unreadable segmenter weights ({type(exc).__name__}); "
                        "retrain them with benchmarks/train_segmenter.py") from exc
    if not isinstance(blob, dict) or blob.get("format") != FORMAT:
        raise UserError(f"{path}: not segmenter weights (no format {FORMAT!r})")
    try:
        model = TinyUNet(tuple(blob["widths"]))
        model.load_state_dict(blob["state"])
    except (KeyError, TypeError, RuntimeError) as exc:
        raise UserError(f"{path}: segmenter weights do not fit the net ({exc})".splitlines()[0]
                        ) from exc
    return fused(model.eval()).to(memory_format=torch.channels_last)  # faster on CPU


def fused(model: TinyUNet) -> TinyUNet:
    """The model (in eval mode) with every batch norm folded into the convolution before it:
    the same function, about a third less inference time."""
    from torch.nn.utils.fusion import fuse_conv_bn_eval

    for block in [*model.down, *model.up]:
        layers = list(block)
        for i in range(len(layers) - 1):
            if isinstance(layers[i], nn.Conv2d) and isinstance(layers[i + 1], nn.BatchNorm2d):
                layers[i], layers[i + 1] = fuse_conv_bn_eval(layers[i], layers[i + 1]), \
                    nn.Identity()
        for i, layer in enumerate(layers):
            block[i] = layer
    return model


@functools.cache
def default_segmenter() -> TinyUNet:
    """The shipped segmenter (`WEIGHTS`), loaded once per process."""
    return load_weights(WEIGHTS)


def to_tensor(rgb: np.ndarray) -> torch.Tensor:
    """(H, W, 3) uint8 RGB to a (1, 3, H, W) float tensor in [0, 1]."""
    return torch.from_numpy(np.ascontiguousarray(rgb)).permute(2, 0, 1)[None].float() / 255.0


def segment_image(rgb: np.ndarray, model: TinyUNet | None = None) -> np.ndarray:
    """(H, W) uint8 labels (0 table, 1 object, 2 index, 3 thumb) of an RGB image."""
    if rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.dtype != np.uint8:
        raise UserError(f"expected an (H, W, 3) uint8 RGB image, got {rgb.shape} {rgb.dtype}")
    model = model or default_segmenter()
    h, w = rgb.shape[:2]
    x = to_tensor(rgb)
    scale = NATIVE_PX / max(h, w)
    if abs(scale - 1.0) > 0.05:  # the scale it was trained at: fingers of the size it knows
        x = nn.functional.interpolate(x, size=(round(h * scale), round(w * scale)),
                                      mode="bilinear", align_corners=False)
    with torch.inference_mode():
        logits = model(x.contiguous(memory_format=torch.channels_last))
        if logits.shape[-2:] != (h, w):
            logits = nn.functional.interpolate(logits, size=(h, w), mode="bilinear",
                                               align_corners=False)
    return logits[0].argmax(0).to(torch.uint8).numpy()


def palette_image(labels: np.ndarray, finger_rgb: dict[str, tuple], table_rgb: tuple
                  ) -> np.ndarray:
    """Labels drawn as a clean render: the table and finger colours (in [0, 1]; a finger at
    full brightness, as overlays are drawn) and `OBJECT_RGB` for the object."""
    out = np.empty((*labels.shape, 3), np.uint8)
    out[:] = np.round(255 * np.asarray(table_rgb, float)).astype(np.uint8)
    out[labels == OBJECT] = OBJECT_RGB
    for f, c in finger_rgb.items():
        c = np.asarray(c, float)
        out[labels == FINGER_LABEL[f]] = np.round(255 * c / max(float(c.max()), 1e-6))
    assert TABLE == 0  # the fill above
    return out


@functools.cache
def weights_digest(path: Path = WEIGHTS) -> str:
    """A short SHA-256 of a weights file ('' when absent): caches of located fingertips key on
    it, so that retrained weights locate anew."""
    import hashlib

    return hashlib.sha256(path.read_bytes()).hexdigest()[:16] if path.is_file() else ""
