"""The reference study's architectures (docs/study.md section 7), registered in table order.

Plain conv/max-pool stacks with a ReLU after every convolution and hidden FC layer and the head
FC(f, w) -> ReLU -> FC(w, w) -> ReLU -> FC(w, 2). The rows the study's tables got wrong
(SchoeConv100-V1, -V5, SchoeConv227-V1, -V2) use the reconstruction described in docs/study.md
section 7. Pools are `MaxPool2d(kernel, stride)` without padding, floor mode. No dropout and no
batch norm: the table lists none.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import torch
from torch import nn

from vistac_learn.models.registry import register_model


class Conv(NamedTuple):
    """conv(kernel, stride, in, out, padding) as written in docs/study.md section 7."""

    kernel: int
    stride: int
    c_in: int
    c_out: int
    padding: int


class Pool(NamedTuple):
    """pool(kernel, stride): max-pool without padding."""

    kernel: int
    stride: int


class ConvFCNet(nn.Module):
    """A conv/max-pool feature stack followed by FC(f, w) -> FC(w, w) -> FC(w, out).

    Args:
        layers: the feature layers in order; the first convolution's input channels are
            replaced by `in_channels`.
        fc_in: f, the flattened size the feature stack produces at `input_size`.
        fc_width: w, the hidden FC width.
        input_size: the square input side in pixels.
        in_channels: image channels.
        out_features: outputs.
    """

    def __init__(
        self,
        layers: Sequence[Conv | Pool],
        fc_in: int,
        fc_width: int,
        input_size: int,
        in_channels: int = 1,
        out_features: int = 2,
    ) -> None:
        super().__init__()
        self.input_size = input_size
        self.in_channels = in_channels
        self.fc_in = fc_in
        self.fc_width = fc_width
        self.features = nn.Sequential(*_build_layers(layers, in_channels))
        self.head = nn.Sequential(
            nn.Flatten(),
            nn.Linear(fc_in, fc_width),
            nn.ReLU(inplace=True),
            nn.Linear(fc_width, fc_width),
            nn.ReLU(inplace=True),
            nn.Linear(fc_width, out_features),
        )
        init_signal_preserving(self)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """Map (B, C, H, W) images to (B, out_features)."""
        return self.head(self.features(x))


def init_signal_preserving(model: nn.Module) -> None:
    """He (Kaiming-normal, fan-in) weights and zero biases for every layer before a ReLU.

    PyTorch's default initialisation of Conv2d and Linear (uniform, gain 1/sqrt(3) of He's)
    divides the variance of the signal by about six at every ReLU layer; through the study's
    five to seven ReLU layers (and sparse, mostly-zero edge images) an untrained SchoeConv100-V3
    answers every image alike: its outputs vary by 2e-4 across images against a label spread of
    0.25, so training starts on a plateau and the study's settings (Adam, lr 1e-4, batch 5)
    take some 60 epochs on 64 images to leave it. He's initialisation keeps the variance of
    the signal through each ReLU layer. The last layer starts small (std 1e-3), so the first
    predictions are near zero rather than large.
    """
    layers = [m for m in model.modules() if isinstance(m, nn.Conv2d | nn.Linear)]
    for m in layers[:-1]:
        nn.init.kaiming_normal_(m.weight, mode="fan_in", nonlinearity="relu")
        if m.bias is not None:
            nn.init.zeros_(m.bias)
    nn.init.normal_(layers[-1].weight, std=1e-3)
    if layers[-1].bias is not None:
        nn.init.zeros_(layers[-1].bias)


def _build_layers(layers: Sequence[Conv | Pool], in_channels: int) -> list[nn.Module]:
    """Turn layer specs into modules: Conv2d + ReLU for a conv, MaxPool2d for a pool.

    Args:
        layers: the specs.
        in_channels: replaces the first convolution's input channels.

    Returns:
        The modules in order.

    Raises:
        ValueError: if consecutive convolutions' channel counts do not chain.
    """
    modules: list[nn.Module] = []
    channels = None
    for spec in layers:
        if isinstance(spec, Pool):
            modules.append(nn.MaxPool2d(spec.kernel, spec.stride))
            continue
        c_in = in_channels if channels is None else spec.c_in
        if channels is not None and spec.c_in != channels:
            raise ValueError(f"conv {spec} takes {spec.c_in} channels, previous gives {channels}")
        modules.append(nn.Conv2d(c_in, spec.c_out, spec.kernel, spec.stride, spec.padding))
        modules.append(nn.ReLU(inplace=True))
        channels = spec.c_out
    return modules


ALEXNET_FEATURES = (
    Conv(11, 4, 1, 96, 0), Pool(3, 2),
    Conv(5, 1, 96, 256, 2), Pool(3, 2),
    Conv(3, 1, 256, 384, 1), Conv(3, 1, 384, 384, 1), Conv(3, 1, 384, 256, 1), Pool(3, 2),
)  # fmt: skip


def _schoe100(kernel: int, padding: int, widths: Sequence[int]) -> tuple[Conv | Pool, ...]:
    """The SchoeConv100-V2 pattern with a given kernel, padding and four channel widths.

    Args:
        kernel: kernel of the four padded convolutions.
        padding: their zero padding.
        widths: output channels of the four padded convolutions; the last conv keeps the last.

    Returns:
        conv pool(2,2) conv pool(2,2) conv pool(3,2) conv pool(2,2) conv(6,1,c,c,0).
    """
    c1, c2, c3, c4 = widths
    return (
        Conv(kernel, 1, 1, c1, padding), Pool(2, 2),
        Conv(kernel, 1, c1, c2, padding), Pool(2, 2),
        Conv(kernel, 1, c2, c3, padding), Pool(3, 2),
        Conv(kernel, 1, c3, c4, padding), Pool(2, 2),
        Conv(6, 1, c4, c4, 0),
    )  # fmt: skip


def _schoe227(widths: Sequence[int]) -> tuple[Conv | Pool, ...]:
    """The reconstructed SchoeConv227 pattern: four 13x13 padded convs, pools (3,2), 13x13 conv.

    Args:
        widths: output channels of the four padded convolutions; the last conv keeps the last.

    Returns:
        The layer specs reaching a 1 x 1 map from 227 px.
    """
    c1, c2, c3, c4 = widths
    return (
        Conv(13, 1, 1, c1, 6), Pool(3, 2),
        Conv(13, 1, c1, c2, 6), Pool(3, 2),
        Conv(13, 1, c2, c3, 6), Pool(3, 2),
        Conv(13, 1, c3, c4, 6), Pool(3, 2),
        Conv(13, 1, c4, c4, 0),
    )  # fmt: skip


SCHOE100_V3 = _schoe100(7, 3, (30, 60, 120, 240))

# name -> (display, layers, f, w, input size, description), in thesis table order.
_STUDY_MODELS: dict[str, tuple[str, tuple[Conv | Pool, ...], int, int, int, str]] = {
    "alexnet": ("AlexNet", ALEXNET_FEATURES, 9216, 4096, 227,
                "AlexNet features (ungrouped, 96-256-384-384-256), 6x6 map"),
    "alexnet-1x1": ("AlexNet-1x1", ALEXNET_FEATURES + (Conv(6, 1, 256, 256, 0),), 256, 160, 227,
                    "AlexNet features + 6x6 conv to a 1x1 map"),
    "randomconv": ("RandomConv", (
        Conv(5, 2, 1, 20, 0), Pool(4, 2),
        Conv(3, 2, 20, 40, 0), Pool(3, 2),
        Conv(3, 2, 40, 80, 0), Pool(3, 2),
    ), 320, 160, 227, "three strided convs, 2x2 map"),
    "smallconv": ("SmallConv", (
        Conv(5, 3, 1, 20, 0), Pool(3, 3),
        Conv(4, 3, 20, 40, 0), Pool(2, 3),
    ), 360, 160, 227, "two strided convs, 3x3 map"),
    "schoeconv100-v1": ("SchoeConv100-V1", (
        Conv(5, 1, 1, 30, 0), Pool(2, 2),
        Conv(5, 1, 30, 60, 0), Pool(2, 2),
        Conv(5, 1, 60, 120, 0), Pool(2, 2),
        Conv(5, 1, 120, 240, 0),
        Conv(5, 1, 240, 240, 0),
    ), 240, 160, 100, "unpadded 5x5 convs (reconstructed row)"),
    "schoeconv100-v2": ("SchoeConv100-V2", _schoe100(5, 2, (30, 60, 120, 240)), 240, 160, 100,
                        "padded 5x5 convs, 6x6 conv to 1x1"),
    "schoeconv100-v3-fc160": ("SchoeConv100-V3(FC160)", SCHOE100_V3, 240, 160, 100,
                              "padded 7x7 convs, 6x6 conv to 1x1"),
    "schoeconv100-v3-fc160-4x4": ("SchoeConv100-V3(FC160)-4x4", SCHOE100_V3[:-2] + (Pool(3, 3),),
                                  3840, 160, 100, "V3 without the last conv, 4x4 map"),
    "schoeconv100-v3-fc480": ("SchoeConv100-V3(FC480)", SCHOE100_V3, 240, 480, 100,
                              "V3 with FC width 480"),
    "schoeconv100-v4": ("SchoeConv100-V4", _schoe100(9, 4, (30, 60, 120, 240)), 240, 160, 100,
                        "padded 9x9 convs, 6x6 conv to 1x1"),
    "schoeconv100-v5": ("SchoeConv100-V5", _schoe100(7, 3, (50, 100, 200, 400)), 400, 160, 100,
                        "V3 with 50-100-200-400 maps (reconstructed row)"),
    "schoeconv227-v1": ("SchoeConv227-V1", _schoe227((30, 60, 120, 240)), 240, 160, 227,
                        "padded 13x13 convs, 30-60-120-240 maps (reconstructed row)"),
    "schoeconv227-v2": ("SchoeConv227-V2", _schoe227((50, 100, 200, 400)), 400, 160, 227,
                        "padded 13x13 convs, 50-100-200-400 maps (reconstructed row)"),
}  # fmt: skip


def _register_study_model(slug: str) -> None:
    """Register one row of the study's architecture table.

    Args:
        slug: key into the table above.
    """
    display, layers, fc_in, fc_width, input_size, description = _STUDY_MODELS[slug]

    def build(in_channels: int = 1, out_features: int = 2) -> nn.Module:
        return ConvFCNet(layers, fc_in, fc_width, input_size, in_channels, out_features)

    build.__name__ = slug.replace("-", "_")
    build.__doc__ = f"{display} (docs/study.md section 7): {description}."
    register_model(slug, display=display, description=description)(build)


for _slug in _STUDY_MODELS:
    _register_study_model(_slug)
