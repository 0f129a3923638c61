"""Whether a run fits in memory, estimated before any work (`check_fits`).

Memory of a training step grows with the square of ``--size``: a model's activations at side S
are (S / S0)^2 those at S0. The estimate runs the model once on torch's "meta" device (shapes
only, no arithmetic, no memory) with forward hooks that add up the outputs of every layer:

- training: weights, their gradients and two optimiser moments (4 x the parameters), plus
  every layer's output for a batch, kept for the backward pass and matched by a gradient of the
  same size (2 x), plus the batch's input (float32 and the rendered uint8 images);
- scoring (after every epoch, ``eval_batch_size`` samples at once, no gradients): the largest
  pair of consecutive layer outputs for a batch.

The estimate is refused when it is above `USABLE` of the memory available now (free device
memory on CUDA, ``MemAvailable`` on a CPU). Measured against the peak resident memory of the
process (benchmarks/train_memory.py), it lies within a factor of two either side.
"""

from __future__ import annotations

import copy
import os

import torch
from torch import nn

from vistac.errors import UserError

BYTES = 4  # float32
USABLE = 0.8  # share of the available memory a run may plan to use


def layer_outputs(model: nn.Module, shape: tuple[int, ...]) -> tuple[int, int]:
    """(sum, largest pair of consecutive) output elements of the leaf layers for one sample.

    Args:
        model: A model taking (1, *shape) (a per-finger model: its shared `net` per crop).
        shape: (C, S, S) of one input.
    """
    meta = copy.deepcopy(model).to("meta")
    sizes: list[int] = []

    def hook(_module, _inputs, output) -> None:
        if isinstance(output, torch.Tensor):
            sizes.append(output.numel())

    handles = [m.register_forward_hook(hook) for m in meta.modules()
               if not list(m.children())]
    try:
        meta.eval()
        with torch.no_grad():
            meta(torch.zeros(1, *shape, device="meta"))
    finally:
        for h in handles:
            h.remove()
    pairs = [a + b for a, b in zip([0, *sizes], sizes, strict=False)]
    return sum(sizes), max(pairs, default=0)


def estimate_bytes(model: nn.Module, channels: int, size: int, batch_size: int,
                   eval_batch_size: int) -> tuple[int, int]:
    """(training, scoring) bytes of a run's model at input side `size`."""
    crops = getattr(model, "n_fingers", 1)  # a per-finger model sees one crop per finger
    net = model.net if hasattr(model, "n_fingers") else model
    total, peak = layer_outputs(net, (channels, size, size))
    params = sum(p.numel() for p in model.parameters())
    pixels = crops * channels * size * size
    train = BYTES * (4 * params + 2 * batch_size * crops * total) + batch_size * pixels * 5
    score = BYTES * (params + eval_batch_size * crops * peak) + eval_batch_size * pixels * 5
    return int(train), int(score)


def available_bytes(device: torch.device) -> int:
    """Memory free for a run now: free CUDA memory, else the system's ``MemAvailable``."""
    if device.type == "cuda":
        return int(torch.cuda.mem_get_info(device)[0])
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return int(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_AVPHYS_PAGES"))


def check_fits(model: nn.Module, channels: int, size: int, batch_size: int,
               eval_batch_size: int, device: torch.device,
               available: int | None = None) -> tuple[int, int]:
    """Refuse, before any work, a run whose estimated memory is above `USABLE` of what is
    available.

    Returns:
        The (training, scoring) estimates in bytes.

    Raises:
        UserError: naming --size and --batch-size, the estimate and what is available; a
            size too small for the model.
    """
    try:
        train, score = estimate_bytes(model, channels, size, batch_size, eval_batch_size)
    except RuntimeError as exc:  # a layer's output would be empty
        raise UserError(f"--size {size}: too small for this model "
                        f"({str(exc).splitlines()[0][:160]})") from None
    have = available_bytes(device) if available is None else available
    need = max(train, score)
    if need > USABLE * have:
        what = "training" if train >= score else f"scoring ({eval_batch_size} samples at once)"
        raise UserError(f"--size {size} --batch-size {batch_size}: {what} needs about "
                        f"{need / 2**30:.1f} GiB, {have / 2**30:.1f} GiB is available on "
                        f"{device.type}; lower --size or --batch-size")
    return train, score
