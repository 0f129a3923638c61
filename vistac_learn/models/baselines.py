"""Efficient baselines (not in the study), written in plain torch and sized for a CPU.

- `resnet-tiny`: a residual net (stem 5x5/2 + max-pool, four BasicBlock stages of 16-32-64-128
  channels with batch norm, global average pooling, one linear layer); 0.31 M parameters,
  60 M MACs at 227 px.
- `mobilenetv2-tiny`: MobileNetV2-style inverted residual blocks (1x1 expand, 3x3 depthwise, 1x1
  linear projection, batch norm, ReLU6), global average pooling, one linear layer; 0.25 M
  parameters, 32 M MACs at 227 px.

Both take any input of at least 32 px thanks to global pooling; their nominal size is 227.
"""

from __future__ import annotations

import torch
from torch import nn

from vistac_learn.models.registry import register_model


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
