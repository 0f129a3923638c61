"""The default model: a small CNN on the fingertip crop, shared by both fingers.

`tipnet` reads one finger's fingertip-centred, finger-aligned crop (`vistac_learn.data.views`,
view ``tip``, 48 x 48 colour) and returns that finger's (r_y, r_z) in the index finger's
convention. Four stages of 3 x 3 convolution, batch norm and ReLU (widths w, 2w, 4w, 4w; 2 x 2
max-pooling between them), global average pooling, FC(4w, 64) -> ReLU -> FC(64, 2). With w = 16:
65 k parameters and 7.8 M multiply-accumulates per finger, 1/85 of SchoeConv100-V3's per image.

`PerFinger` runs any registered model on each finger's crop of a per-finger view: input
(B, F, C, S, S), output (B, 2F), one set of weights for every finger (the view mirrors the
thumb's crop so that its labels read like the index finger's). When the view adds side features
per finger (B, F, K) (where the other fingertip is), the model's output is an embedding of
`embed` numbers instead of the two label components, and a small fusion head maps embedding and
side features to (r_y, r_z): FC(embed + K, 64) -> ReLU -> FC(64, 2).
"""

from __future__ import annotations

import torch
from torch import nn

from vistac_learn.models.registry import register_model


def _stage(c_in: int, c_out: int) -> nn.Sequential:
    return nn.Sequential(nn.Conv2d(c_in, c_out, 3, padding=1, bias=False), nn.BatchNorm2d(c_out),
                         nn.ReLU(inplace=True))


class TipNet(nn.Module):
    """Conv-BN-ReLU stages, global average pooling and a two-layer head.

    Args:
        in_channels: Image channels.
        out_features: Outputs (2 per finger the model sees at once).
        width: Channels of the first stage.
        hidden: Width of the hidden FC layer.
    """

    def __init__(self, in_channels: int = 3, out_features: int = 2, width: int = 16,
                 hidden: int = 64):
        super().__init__()
        w = width
        self.input_size, self.in_channels = 48, in_channels
        self.fc_in, self.fc_width = 4 * w, hidden
        self.features = nn.Sequential(
            _stage(in_channels, w), nn.MaxPool2d(2), _stage(w, 2 * w), nn.MaxPool2d(2),
            _stage(2 * w, 4 * w), nn.MaxPool2d(2), _stage(4 * w, 4 * w),
            nn.AdaptiveAvgPool2d(1), nn.Flatten())
        self.head = nn.Sequential(nn.Linear(4 * w, hidden), nn.ReLU(inplace=True),
                                  nn.Linear(hidden, out_features))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """Map (B, C, S, S) crops to (B, out_features)."""
        return self.head(self.features(x))


@register_model("tipnet", display="TipNet",
                description="default: 4 conv-BN-ReLU stages on a 48 px fingertip crop")
def tipnet(in_channels: int = 3, out_features: int = 2) -> nn.Module:
    """TipNet with width 16 (65 k parameters, 7.8 M MACs per 48 px crop)."""
    return TipNet(in_channels, out_features)


class PerFinger(nn.Module):
    """Apply one model to every finger's crop: (B, F, C, S, S) [+ side (B, F, K)] -> (B, 2F).

    Args:
        net: A model mapping (N, C, S, S) to (N, 2), or to (N, embed) when side features come.
        n_fingers: F.
        side_features: K, numbers per finger beside the pixels (0: none).
        embed: Width of `net`'s output when K > 0.
    """

    def __init__(self, net: nn.Module, n_fingers: int, side_features: int = 0,
                 embed: int = 32):
        super().__init__()
        self.net = net
        self.n_fingers, self.side_features = n_fingers, side_features
        self.fuse = None
        if side_features:
            self.fuse = nn.Sequential(nn.Linear(embed + side_features, 64), nn.ReLU(inplace=True),
                                      nn.Linear(64, 2))
        for name in ("input_size", "in_channels", "fc_in", "fc_width", "name"):
            if hasattr(net, name):
                setattr(self, name, getattr(net, name))

    def forward(self, x: torch.Tensor, side: torch.Tensor | None = None) -> torch.Tensor:
        """Run the shared model on each finger's crop (and its side features)."""
        b, f = x.shape[:2]
        out = self.net(x.reshape(b * f, *x.shape[2:]))
        if self.fuse is not None:
            out = self.fuse(torch.cat([out, side.reshape(b * f, -1)], dim=1))
        return out.reshape(b, 2 * f)


def apply_model(model: nn.Module, batch: dict, device) -> torch.Tensor:
    """The model's output on a batch of `SampleSet.batch`, side features passed if it takes
    them."""
    x = batch["image"].to(device)
    if getattr(model, "side_features", 0):
        return model(x, batch["side"].to(device))
    return model(x)
