"""What a training step minimises: the label MSE, plus the auxiliary contact losses of models
that predict contact geometry (`vistac_learn.models.pinch.PinchModel`)."""

from __future__ import annotations

import torch

from vistac_learn.models.tipnet import apply_model


def masked_mse(pred: torch.Tensor, target: torch.Tensor, found: torch.Tensor) -> torch.Tensor:
    """MSE over the fingers that were located (every finger for views that locate none)."""
    w = found.to(pred.dtype).repeat_interleave(2, dim=1)
    return ((pred - target) ** 2 * w).sum() / w.sum().clamp_min(1.0)


def batch_loss(model: torch.nn.Module, batch: dict, device, aux_weight: float = 1.0
               ) -> torch.Tensor:
    """The training loss of one batch of `SampleSet.batch`.

    For a model with ``auxiliary = True`` and ``aux_weight > 0``: label MSE + aux_weight x the
    model's `aux_loss` on the batch's auxiliary targets (rows without truth add nothing).
    """
    y, found = batch["target"].to(device), batch["found"].to(device)
    if getattr(model, "auxiliary", False) and aux_weight > 0:
        pred, aux = model(batch["image"].to(device), batch["side"].to(device), aux=True)
        return masked_mse(pred, y, found) + aux_weight * model.aux_loss(
            aux, batch["aux"].to(device))
    return masked_mse(apply_model(model, batch, device), y, found)
