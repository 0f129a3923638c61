"""The model registry: builders registered by name, `create_model` and `model_info`."""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass

import torch
from torch import nn

from vistac_learn.models.macs import count_macs


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
        description: one line, returned by `model_info` (``"description"``).

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
