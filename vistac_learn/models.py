"""Model zoo: the reference study's CNNs and efficient modern baselines, registered by name.

timm-style registry: a builder function is registered with `@register_model("slug")`, and
`create_model(name, in_channels, out_features)` builds it from a string, so that the CLI, the
trainer and a tuner pick models by name.

Study architectures (thesis.md section 7): plain conv/max-pool stacks with a ReLU after every
convolution and hidden FC layer and the head FC(f, w) -> ReLU -> FC(w, w) -> ReLU -> FC(w, 2). The
rows the study's tables got wrong (SchoeConv100-V1, -V5, SchoeConv227-V1, -V2) use the
reconstruction given in thesis.md. Pools are `MaxPool2d(kernel, stride)` without padding, floor
mode. No dropout and no batch norm: the table lists none.

Efficient baselines (not in the study), written in plain torch and sized for a CPU:
- `resnet-tiny`: a residual net (stem 5x5/2 + max-pool, four BasicBlock stages of 16-32-64-128
  channels with batch norm, global average pooling, one linear layer); 0.31 M parameters,
  60 M MACs at 227 px.
- `mobilenetv2-tiny`: MobileNetV2-style inverted residual blocks (1x1 expand, 3x3 depthwise, 1x1
  linear projection, batch norm, ReLU6), global average pooling, one linear layer; 0.25 M
  parameters, 32 M MACs at 227 px.
Both take any input of at least 32 px thanks to global pooling; their nominal size is 227.

Every model carries `input_size` (100 or 227), `in_channels`, `fc_in` (f, the input width of the
first FC layer) and `fc_width` (w, the hidden FC width; None for the baselines, whose head is a
single linear layer).

Cost: `count_macs` counts multiply-accumulates (not FLOPs) of Conv2d and Linear layers with
forward hooks, for one image: a convolution costs out_h * out_w * out_c * (in_c / groups) * k_h *
k_w, a linear layer out_features * in_features. Biases, ReLU, pooling, batch norm (foldable into
the preceding convolution) and residual additions are not counted. `model_info` builds the model
on torch's "meta" device, so the count runs no arithmetic and costs nothing.

Against the thesis's forward costs: SchoeConv100-V3 0.661 G (0.66 G stated), SchoeConv100-V5
1.820 G (1.8 G), SchoeConv227-V1 11.52 G (11.5 G), SchoeConv227-V2 31.71 G (31.7 G). AlexNet
(ungrouped, one input channel) counts 1.061 G, 6 % above the stated 1.0 G; its conv layers alone
count 1.006 G, so the thesis figure evidently leaves out (or rounds away) the 54.5 M MACs of the
FC head.
"""

from __future__ import annotations

import argparse
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import NamedTuple

import torch
from torch import nn

__all__ = [
    "register_model",
    "create_model",
    "list_models",
    "model_info",
    "count_macs",
    "format_table",
    "add_command",
]


# --------------------------------------------------------------------------------------------
# Registry
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Entry:
    """One registered model: its slug, thesis spelling, builder and short description."""

    slug: str
    display: str
    builder: Callable[..., nn.Module]
    description: str


_REGISTRY: dict[str, _Entry] = {}
_ALIASES: dict[str, str] = {}


def _normalize(name: str) -> str:
    """Map a model name to its lookup key: lower case, brackets/spaces/underscores to dashes.

    Args:
        name: a slug ("schoeconv100-v3-fc160") or thesis spelling ("SchoeConv100-V3(FC160)").

    Returns:
        The normalized key, e.g. "schoeconv100-v3-fc160".
    """
    key = re.sub(r"[()\s_]+", "-", name.strip().lower())
    return re.sub(r"-{2,}", "-", key).strip("-")


def register_model(
    name: str, *, display: str | None = None, description: str = ""
) -> Callable[[Callable[..., nn.Module]], Callable[..., nn.Module]]:
    """Register a model builder under a CLI-friendly name (decorator).

    The builder takes `in_channels` and `out_features` keywords and returns an `nn.Module`.

    Args:
        name: lower-case slug, e.g. "schoeconv100-v3-fc160".
        display: the thesis spelling, e.g. "SchoeConv100-V3(FC160)"; also accepted by
            `create_model` (case-insensitively). Defaults to `name`.
        description: one line shown by `vistac models --long` and `model_info`.

    Returns:
        The decorator, which returns the builder unchanged.

    Raises:
        ValueError: if `name` is not a normalized slug or is already registered.
    """
    if _normalize(name) != name:
        raise ValueError(f"model name {name!r} is not a lower-case slug ({_normalize(name)!r})")
    if name in _REGISTRY:
        raise ValueError(f"model {name!r} is already registered")

    def decorator(builder: Callable[..., nn.Module]) -> Callable[..., nn.Module]:
        entry = _Entry(name, display or name, builder, description)
        _REGISTRY[name] = entry
        _ALIASES[name] = name
        _ALIASES[_normalize(entry.display)] = name
        return builder

    return decorator


def _resolve(name: str) -> _Entry:
    """Find a registered model by slug or thesis spelling.

    Args:
        name: model name, any case.

    Returns:
        The registry entry.

    Raises:
        ValueError: for an unknown name, listing the valid ones.
    """
    slug = _ALIASES.get(_normalize(name))
    if slug is None:
        raise ValueError(f"unknown model {name!r}; valid names: {', '.join(list_models())}")
    return _REGISTRY[slug]


def list_models() -> list[str]:
    """Names of all registered models, study architectures first, in thesis table order.

    Returns:
        The slugs, e.g. ["alexnet", "alexnet-1x1", ...].
    """
    return list(_REGISTRY)


def create_model(name: str, in_channels: int = 1, out_features: int = 2) -> nn.Module:
    """Build a registered model with freshly initialised weights.

    Args:
        name: slug ("schoeconv100-v3-fc160") or thesis spelling ("SchoeConv100-V3(FC160)"),
            case-insensitive.
        in_channels: image channels: 1 for edge images, 3 for colour.
        out_features: outputs: 2 for (r_y, r_z) of one finger, 4 for both fingers.

    Returns:
        The model, with attributes `input_size`, `in_channels`, `fc_in`, `fc_width` and `name`.

    Raises:
        ValueError: for an unknown name or non-positive channel/feature counts.
    """
    entry = _resolve(name)
    if in_channels < 1 or out_features < 1:
        raise ValueError(f"in_channels and out_features must be >= 1, got {in_channels}, "
                         f"{out_features}")
    model = entry.builder(in_channels=in_channels, out_features=out_features)
    model.name = entry.slug
    return model


def count_macs(model: nn.Module, input_shape: Sequence[int] | None = None) -> int:
    """Count the multiply-accumulates of Conv2d and Linear layers for one image.

    The model runs one forward pass on zeros with forward hooks; on a model built on the
    "meta" device this computes only shapes.

    Args:
        model: the network.
        input_shape: (channels, height, width); defaults to (model.in_channels,
            model.input_size, model.input_size).

    Returns:
        Multiply-accumulates per image.
    """
    if input_shape is None:
        input_shape = (model.in_channels, model.input_size, model.input_size)
    total = 0

    def conv_hook(module: nn.Conv2d, _inputs: tuple, output: torch.Tensor) -> None:
        nonlocal total
        k_h, k_w = module.kernel_size
        per_out = (module.in_channels // module.groups) * k_h * k_w
        total += output[0].numel() * per_out

    def linear_hook(module: nn.Linear, _inputs: tuple, output: torch.Tensor) -> None:
        nonlocal total
        total += output[0].numel() * module.in_features

    handles = []
    for module in model.modules():
        if isinstance(module, nn.Conv2d):
            handles.append(module.register_forward_hook(conv_hook))
        elif isinstance(module, nn.Linear):
            handles.append(module.register_forward_hook(linear_hook))
    param = next(model.parameters())
    was_training = model.training
    try:
        model.eval()
        with torch.no_grad():
            model(torch.zeros(1, *input_shape, device=param.device, dtype=param.dtype))
    finally:
        model.train(was_training)
        for handle in handles:
            handle.remove()
    return int(total)


def model_info(name: str, in_channels: int = 1, out_features: int = 2) -> dict:
    """Size and cost of a registered model, computed on the meta device (no arithmetic).

    Args:
        name: model name (slug or thesis spelling).
        in_channels: image channels the count assumes.
        out_features: outputs the count assumes.

    Returns:
        {"name", "display", "description", "input_size", "in_channels", "params", "macs",
        "fc_in", "fc_width"}; params counts every trainable parameter, macs is per image at
        the model's input size.

    Raises:
        ValueError: for an unknown name.
    """
    entry = _resolve(name)
    with torch.device("meta"):
        model = create_model(entry.slug, in_channels, out_features)
    return {
        "name": entry.slug,
        "display": entry.display,
        "description": entry.description,
        "input_size": model.input_size,
        "in_channels": in_channels,
        "params": sum(p.numel() for p in model.parameters() if p.requires_grad),
        "macs": count_macs(model),
        "fc_in": model.fc_in,
        "fc_width": model.fc_width,
    }


# --------------------------------------------------------------------------------------------
# The study's conv stacks
# --------------------------------------------------------------------------------------------


class Conv(NamedTuple):
    """conv(kernel, stride, in, out, padding) as written in thesis.md section 7."""

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

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """Map (B, C, H, W) images to (B, out_features)."""
        return self.head(self.features(x))


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
    build.__doc__ = f"{display} (thesis.md section 7): {description}."
    register_model(slug, display=display, description=description)(build)


for _slug in _STUDY_MODELS:
    _register_study_model(_slug)


# --------------------------------------------------------------------------------------------
# Efficient baselines
# --------------------------------------------------------------------------------------------


def _conv_bn(c_in: int, c_out: int, kernel: int, stride: int = 1, groups: int = 1) -> nn.Sequential:
    """Conv2d (no bias, 'same'-style padding) followed by BatchNorm2d.

    Args:
        c_in: input channels.
        c_out: output channels.
        kernel: odd kernel size.
        stride: stride.
        groups: convolution groups (c_in for depthwise).

    Returns:
        The two-layer block.
    """
    return nn.Sequential(
        nn.Conv2d(c_in, c_out, kernel, stride, kernel // 2, groups=groups, bias=False),
        nn.BatchNorm2d(c_out),
    )


class BasicBlock(nn.Module):
    """ResNet basic block: 3x3 conv-BN-ReLU, 3x3 conv-BN, add the (projected) input, ReLU.

    Args:
        c_in: input channels.
        c_out: output channels.
        stride: stride of the first convolution (and of the 1x1 projection).
    """

    def __init__(self, c_in: int, c_out: int, stride: int = 1) -> None:
        super().__init__()
        self.conv1 = _conv_bn(c_in, c_out, 3, stride)
        self.conv2 = _conv_bn(c_out, c_out, 3)
        nn.init.zeros_(self.conv2[1].weight)  # each block starts as the identity
        self.shortcut = (
            _conv_bn(c_in, c_out, 1, stride) if stride != 1 or c_in != c_out else nn.Identity()
        )
        self.relu = nn.ReLU(inplace=True)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """Apply the block."""
        return self.relu(self.conv2(self.relu(self.conv1(x))) + self.shortcut(x))


class InvertedResidual(nn.Module):
    """MobileNetV2 block: 1x1 expand-BN-ReLU6, 3x3 depthwise-BN-ReLU6, 1x1 project-BN (+ input).

    Args:
        c_in: input channels.
        c_out: output channels.
        stride: stride of the depthwise convolution.
        expand: expansion ratio of the hidden width.
    """

    def __init__(self, c_in: int, c_out: int, stride: int, expand: int) -> None:
        super().__init__()
        hidden = c_in * expand
        layers: list[nn.Module] = []
        if expand != 1:
            layers += [_conv_bn(c_in, hidden, 1), nn.ReLU6(inplace=True)]
        layers += [_conv_bn(hidden, hidden, 3, stride, groups=hidden), nn.ReLU6(inplace=True),
                   _conv_bn(hidden, c_out, 1)]
        self.block = nn.Sequential(*layers)
        self.residual = stride == 1 and c_in == c_out

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """Apply the block."""
        out = self.block(x)
        return x + out if self.residual else out


class PooledNet(nn.Module):
    """Feature stack, global average pooling and one linear layer.

    Args:
        features: the convolutional stack, ending with `fc_in` channels.
        fc_in: channels entering the linear layer.
        input_size: nominal square input side in pixels (any size >= 32 works).
        in_channels: image channels.
        out_features: outputs.
    """

    def __init__(
        self, features: nn.Module, fc_in: int, input_size: int, in_channels: int, out_features: int
    ) -> None:
        super().__init__()
        self.input_size = input_size
        self.in_channels = in_channels
        self.fc_in = fc_in
        self.fc_width = None
        self.features = features
        self.pool = nn.AdaptiveAvgPool2d(1)
        self.head = nn.Linear(fc_in, out_features)
        _init_weights(self)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """Map (B, C, H, W) images to (B, out_features)."""
        return self.head(torch.flatten(self.pool(self.features(x)), 1))


def _init_weights(model: nn.Module) -> None:
    """Kaiming-normal conv weights (fan-out); zero biases; BN weights left as set.

    Args:
        model: the network, initialised in place.
    """
    for module in model.modules():
        if isinstance(module, nn.Conv2d):
            nn.init.kaiming_normal_(module.weight, mode="fan_out", nonlinearity="relu")
        elif isinstance(module, nn.Linear):
            nn.init.zeros_(module.bias)


@register_model("resnet-tiny", display="ResNet-tiny",
                description="baseline: residual net 16-32-64-128, BN, global avg pool")
def resnet_tiny(in_channels: int = 1, out_features: int = 2) -> nn.Module:
    """A small ResNet for 227 px: stem 5x5/2 + max-pool 3/2, four basic blocks, GAP, linear.

    Args:
        in_channels: image channels.
        out_features: outputs.

    Returns:
        The model (0.31 M parameters, 60 M MACs at 227 px).
    """
    widths = (16, 32, 64, 128)
    stages: list[nn.Module] = [
        _conv_bn(in_channels, widths[0], 5, 2), nn.ReLU(inplace=True), nn.MaxPool2d(3, 2, 1),
    ]
    c_in = widths[0]
    for i, c_out in enumerate(widths):
        stages.append(BasicBlock(c_in, c_out, stride=1 if i == 0 else 2))
        c_in = c_out
    return PooledNet(nn.Sequential(*stages), widths[-1], 227, in_channels, out_features)


@register_model("mobilenetv2-tiny", display="MobileNetV2-tiny",
                description="baseline: depthwise-separable inverted residuals, BN, global avg pool")
def mobilenetv2_tiny(in_channels: int = 1, out_features: int = 2) -> nn.Module:
    """A small MobileNetV2 for 227 px: stem 3x3/2, inverted residual blocks, 1x1 conv, GAP, linear.

    Args:
        in_channels: image channels.
        out_features: outputs.

    Returns:
        The model (0.25 M parameters, 32 M MACs at 227 px).
    """
    # (expansion, output channels, repeats, first stride), as in MobileNetV2's table, narrowed.
    plan = ((1, 16, 1, 2), (4, 24, 2, 2), (4, 32, 2, 2), (4, 64, 2, 2), (4, 96, 1, 1),
            (4, 128, 1, 1))
    layers: list[nn.Module] = [_conv_bn(in_channels, 16, 3, 2), nn.ReLU6(inplace=True)]
    c_in = 16
    for expand, c_out, repeats, stride in plan:
        for i in range(repeats):
            layers.append(InvertedResidual(c_in, c_out, stride if i == 0 else 1, expand))
            c_in = c_out
    last = 256
    layers += [_conv_bn(c_in, last, 1), nn.ReLU6(inplace=True)]
    return PooledNet(nn.Sequential(*layers), last, 227, in_channels, out_features)


# --------------------------------------------------------------------------------------------
# `vistac models`
# --------------------------------------------------------------------------------------------


def human(value: float, unit: str) -> str:
    """Format a count in a fixed unit with three significant digits ("0.661 G", "58.3 M").

    One unit per table column keeps the rows comparable at a glance.

    Args:
        value: a non-negative count.
        unit: "k", "M" or "G".

    Returns:
        The formatted string.
    """
    factor = {"k": 1e3, "M": 1e6, "G": 1e9}[unit]
    return f"{value / factor:.3g} {unit}"


def format_table(infos: Sequence[dict]) -> str:
    """Render model infos as a text table: name, input, params, MACs, f, w.

    Args:
        infos: dicts from `model_info`.

    Returns:
        The table, one line per model, with a header line.
    """
    header = ("name", "thesis name", "input", "params", "MACs", "f", "w")
    rows = [
        (
            i["name"], i["display"], str(i["input_size"]),
            human(i["params"], "M"), human(i["macs"], "G"),
            str(i["fc_in"]), "-" if i["fc_width"] is None else str(i["fc_width"]),
        )
        for i in infos
    ]
    widths = [max(len(r[c]) for r in (header, *rows)) for c in range(len(header))]
    left = 2  # name columns left-aligned, numbers right-aligned

    def line(row: Sequence[str]) -> str:
        return "  ".join(
            cell.ljust(width) if c < left else cell.rjust(width)
            for c, (cell, width) in enumerate(zip(row, widths, strict=True))
        ).rstrip()

    return "\n".join([line(header), *(line(r) for r in rows)])


def _run_models(args: argparse.Namespace) -> int:
    """Print the model table (the `vistac models` command).

    Args:
        args: parsed arguments with `in_channels` and `out_features`.

    Returns:
        Exit code 0.
    """
    infos = [model_info(name, args.in_channels, args.out_features) for name in list_models()]
    print(format_table(infos))
    print(f"MACs = multiply-accumulates of Conv2d/Linear for one {args.in_channels}-channel image "
          "at the model's input size.")
    return 0


def add_command(sub: argparse._SubParsersAction) -> None:
    """Add the `models` sub-command to the `vistac` parser.

    Args:
        sub: the top-level sub-parsers object.
    """
    parser = sub.add_parser(
        "models",
        help="list the registered models with parameters and multiply-accumulates",
        description="List every registered model: input size, parameters, multiply-accumulates "
        "per image, FC input size f and FC width w.",
    )
    parser.add_argument("--in-channels", type=int, default=1,
                        help="image channels (1 = edge image, 3 = colour; default 1)")
    parser.add_argument("--out-features", type=int, default=2,
                        help="outputs (2 = one finger, 4 = both; default 2)")
    parser.set_defaults(func=_run_models)
