"""Cost of a model: multiply-accumulates of its Conv2d and Linear layers for one image.

`count_macs` counts multiply-accumulates (not FLOPs) with forward hooks: a convolution costs
out_h * out_w * out_c * (in_c / groups) * k_h * k_w, a linear layer out_features * in_features.
Biases, ReLU, pooling, batch norm (foldable into the preceding convolution) and residual
additions are not counted. `model_info` builds the model on torch's "meta" device, so the count
runs no arithmetic and costs nothing.

Against the thesis's forward costs: SchoeConv100-V3 0.661 G (0.66 G stated), SchoeConv100-V5
1.820 G (1.8 G), SchoeConv227-V1 11.52 G (11.5 G), SchoeConv227-V2 31.71 G (31.7 G). AlexNet
(ungrouped, one input channel) counts 1.061 G, 6 % above the stated 1.0 G; its conv layers alone
count 1.006 G, so the thesis figure evidently leaves out (or rounds away) the 54.5 M MACs of the
FC head.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import nn


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
