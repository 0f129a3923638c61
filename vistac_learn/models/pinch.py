"""The default model: contact geometry read from both fingertip crops, the label composed from it.

Why: both fingers are pushed along the closing axis, the line through the two contact points,
so a sticking pad's force is that axis seen in the finger's frame, turned back into the friction
cone around the contact normal when it leaves it. Measured on a 3000-configuration dataset
(benchmarks/pinch_prior.py): the simulator's own contact points and normals composed this way
score 0.78 / 0.76 deg median angle to the cone mean on held-out objects (index / thumb; the noise
floor is 0.77 / 0.78), the line between the located fingertip centres only 1.94 / 1.85. What
a network must add is where on the rounded pad each finger touches (sub-pixel) and the normal.

`PinchModel` (view ``pinch``, `vistac_learn.data.pinch_view`): one backbone (default `pinchnet`)
embeds each finger's crop; a linear head per crop predicts the contact point ``p`` (crop frame,
units of the crop's half side, 0 = the front of the pad where the crop is centred) and the
contact normal ``n`` (label coordinates) and ``phi``, the tilt of the true finger axis against
the crop's (the crop follows the located axis and the training jitter). `compose_labels` then
forms, for each finger, differentiably,

    v = p_this - (d + rho * T @ p_other)        (contact to contact, this crop's frame)
    l = rotate((-v_x, v_y) / |v|, phi)          (the closing axis as (r_y, r_z))
    label = rotate(n, clamp(angle(n -> l), -atan(mu), atan(mu)))

with the simulator's friction coefficient mu = 0.8 (a fixed buffer; a first version learnt mu
and a free residual turn: on the validation split mu drifted to 0.75 and the residual made the
index finger worse, 1.06 against 1.00 deg without it). With ``aux=True`` the model also
returns ``p``, ``n`` and ``phi`` so that training can supervise them with
the simulator's truth (`aux_loss`); data without that truth (real recordings) trains on the
labels alone.

`pinchnet`: CoordConv (two coordinate channels), four conv-BN-ReLU stages (w, 2w, 4w, 4w;
2 x 2 max-pooling between), a 1 x 1 convolution to 16 channels, 6 x 6 adaptive average pooling
kept as a spatial map (positions matter here), FC(576, 128) -> ReLU -> FC(128, out).
"""

from __future__ import annotations

import torch
from torch import nn

from vistac.dataset import FINGERS
from vistac_learn.data.pinch_view import CONTACT_FEATURES, PAIR_FEATURES
from vistac_learn.models.registry import register_model
from vistac_learn.models.tipnet import _stage

EMBED = 64  # width of the backbone's output per crop
MU = 0.8  # the simulator's friction coefficient
NORMAL_WEIGHT = 0.1  # of the normal's auxiliary loss relative to the contact point's


class AddCoords(nn.Module):
    """Append two channels: x and y of every pixel, in [-1, 1] (CoordConv)."""

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """(B, C, H, W) -> (B, C + 2, H, W)."""
        b, _, h, w = x.shape
        ys = torch.linspace(-1.0, 1.0, h, dtype=x.dtype, device=x.device)
        xs = torch.linspace(-1.0, 1.0, w, dtype=x.dtype, device=x.device)
        gy, gx = torch.meshgrid(ys, xs, indexing="ij")
        return torch.cat([x, gx.expand(b, 1, h, w), gy.expand(b, 1, h, w)], dim=1)


class PinchNet(nn.Module):
    """CoordConv CNN keeping a coarse spatial map before its FC head.

    Args:
        in_channels: Image channels.
        out_features: Outputs.
        width: Channels of the first stage.
        hidden: Width of the hidden FC layer.
    """

    def __init__(self, in_channels: int = 3, out_features: int = EMBED, width: int = 16,
                 hidden: int = 128):
        super().__init__()
        w = width
        self.input_size, self.in_channels = 48, in_channels
        self.fc_in, self.fc_width = 16 * 36, hidden
        self.features = nn.Sequential(
            AddCoords(), _stage(in_channels + 2, w), nn.MaxPool2d(2), _stage(w, 2 * w),
            nn.MaxPool2d(2), _stage(2 * w, 4 * w), nn.MaxPool2d(2), _stage(4 * w, 4 * w),
            nn.Conv2d(4 * w, 16, 1), nn.ReLU(inplace=True), nn.AdaptiveAvgPool2d(6),
            nn.Flatten())
        self.head = nn.Sequential(nn.Linear(self.fc_in, hidden), nn.ReLU(inplace=True),
                                  nn.Linear(hidden, out_features))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """Map (B, C, S, S) crops to (B, out_features)."""
        return self.head(self.features(x))


@register_model("pinchnet", display="PinchNet",
                description="default: CoordConv CNN on a 48 px fingertip crop, spatial head")
def pinchnet(in_channels: int = 3, out_features: int = 2) -> nn.Module:
    """PinchNet with width 16."""
    return PinchNet(in_channels, out_features)


def _rotate(v: torch.Tensor, angle: torch.Tensor) -> torch.Tensor:
    """Vectors (..., 2) turned counter-clockwise by `angle` (...) radians."""
    c, s = torch.cos(angle), torch.sin(angle)
    return torch.stack([c * v[..., 0] - s * v[..., 1], s * v[..., 0] + c * v[..., 1]], dim=-1)


def closing_axis(p: torch.Tensor, side: torch.Tensor) -> torch.Tensor:
    """Per finger, the unit (r_y, r_z) of the line from the other finger's contact to this one's.

    Args:
        p: (B, 2, 2) contact points, each in its own crop's frame (`pinch_view` units).
        side: (B, 2, PAIR_FEATURES) the view's side numbers.

    Returns:
        (B, 2, 2); (0, -1) where a finger was not located (``ok`` = 0).
    """
    d, t = side[..., 0:2], side[..., 2:6].reshape(*side.shape[:2], 2, 2)
    rho, ok = side[..., 6:7], side[..., 7:8] > 0.5
    other = p.flip(1)  # (index, thumb) -> (thumb, index)
    v = p - (d + rho * (t @ other.unsqueeze(-1)).squeeze(-1))
    label = torch.stack([-v[..., 0], v[..., 1]], dim=-1)
    label = label / label.norm(dim=-1, keepdim=True).clamp_min(1e-6)
    return torch.where(ok, label, torch.tensor([0.0, -1.0], dtype=p.dtype, device=p.device))


def compose_labels(p: torch.Tensor, normal: torch.Tensor, phi: torch.Tensor,
                   delta: torch.Tensor, side: torch.Tensor, mu: torch.Tensor | float
                   ) -> torch.Tensor:
    """Labels (B, 2, 2) from contact points, normals (B, 2, 2, unit), crop tilts and residual
    turns (B, 2) and the friction coefficient: the closing axis turned by `phi` into the
    finger's frame, clamped to the cone of half-angle atan(mu) around the normal, turned by
    `delta`."""
    axis = _rotate(closing_axis(p, side), phi)
    n = normal / normal.norm(dim=-1, keepdim=True).clamp_min(1e-6)
    cross = n[..., 0] * axis[..., 1] - n[..., 1] * axis[..., 0]
    angle = torch.atan2(cross, (n * axis).sum(-1))
    half = torch.atan(torch.as_tensor(mu, dtype=p.dtype, device=p.device))
    return _rotate(n, torch.maximum(torch.minimum(angle, half), -half) + delta)


class PinchModel(nn.Module):
    """Backbone on both crops -> contact points, normals, tilts -> composed labels.

    Args:
        net: Backbone mapping (N, C, S, S) crops to (N, `embed`).
        fingers: Fingers whose labels are output, in order (2 values each).
        embed: Width of the backbone's output.
        mu: Friction coefficient of the clamp.
    """

    auxiliary = True  # returns contact geometry with aux=True (see `aux_loss`)
    n_fingers = len(FINGERS)  # crops per sample
    side_features = PAIR_FEATURES

    def __init__(self, net: nn.Module, fingers: tuple[str, ...] = FINGERS, embed: int = EMBED,
                 mu: float = MU):
        super().__init__()
        self.net = net
        self.select = [FINGERS.index(f) for f in fingers]
        self.contact = nn.Linear(embed, CONTACT_FEATURES)
        nn.init.normal_(self.contact.weight, std=1e-3)  # start at the bare prior
        nn.init.zeros_(self.contact.bias)
        self.register_buffer("mu", torch.tensor(float(mu)))
        for name in ("input_size", "in_channels", "fc_in", "fc_width", "name"):
            if hasattr(net, name):
                setattr(self, name, getattr(net, name))

    def geometry(self, x: torch.Tensor, side: torch.Tensor) -> dict[str, torch.Tensor]:
        """{p, normal, phi} of a batch: (B, 2, 2), (B, 2, 2) unit, (B, 2)."""
        b, f = x.shape[:2]
        e = self.net(x.reshape(b * f, *x.shape[2:]))
        c = self.contact(e).reshape(b, f, CONTACT_FEATURES)
        p = c[..., 0:2]
        n = c[..., 2:4] + torch.tensor([0.0, -1.0], dtype=x.dtype, device=x.device)
        n = n / n.norm(dim=-1, keepdim=True).clamp_min(1e-6)
        return {"p": p, "normal": n, "phi": 0.1 * c[..., 4]}

    def forward(self, x: torch.Tensor, side: torch.Tensor, aux: bool = False):
        """(B, 2F') labels of the selected fingers from crops (B, 2, C, S, S) and side numbers
        (B, 2, K); with `aux`, also the geometry of both fingers (`geometry`)."""
        g = self.geometry(x, side)
        labels = compose_labels(g["p"], g["normal"], g["phi"], torch.zeros_like(g["phi"]), side,
                                self.mu)
        out = labels[:, self.select].reshape(x.shape[0], -1)
        return (out, g) if aux else out

    @staticmethod
    def aux_loss(aux: dict[str, torch.Tensor], target: torch.Tensor) -> torch.Tensor:
        """Squared errors of contact points and crop tilts plus `NORMAL_WEIGHT` x those of the
        normals, averaged over the fingers whose truth is known (`target`
        (B, 2, CONTACT_FEATURES), NaN where unknown); 0 if none is."""
        known = torch.isfinite(target).all(dim=-1)
        if not bool(known.any()):
            return aux["p"].sum() * 0.0
        t = target[known]
        lp = ((aux["p"][known] - t[:, 0:2]) ** 2).sum(-1)
        ln = ((aux["normal"][known] - t[:, 2:4]) ** 2).sum(-1)
        lphi = (aux["phi"][known] - t[:, 4]) ** 2
        return (lp + lphi + NORMAL_WEIGHT * ln).mean()


__all__ = ["AddCoords", "PinchModel", "PinchNet", "closing_axis", "compose_labels", "pinchnet"]
