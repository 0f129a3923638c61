"""What a run's settings build (`vistac_learn.train.build`): the model's weights are a function
of the seed alone, drawn in a seed scope that leaves torch's global random state as it was."""

from __future__ import annotations

import pytest
import torch

from vistac_learn.train.build import _new_model, build_model
from vistac_learn.train.config import protocol_cfg

pytestmark = pytest.mark.usefixtures("one_torch_thread")  # tests/conftest.py


def _weights(model: torch.nn.Module) -> list[torch.Tensor]:
    return [t.clone() for t in model.state_dict().values()]


@pytest.mark.parametrize("variant", ["pinch", "tip"])
def test_build_model_draws_in_a_seed_scope(variant):
    cfg = protocol_cfg("default", "", "", variant=variant, model="tipnet", seed=5)
    torch.manual_seed(1)
    state = torch.get_rng_state()
    first = _weights(build_model(cfg))
    assert torch.equal(torch.get_rng_state(), state)  # the caller's draws are untouched
    torch.rand(100)  # whatever ran before
    again = _weights(build_model(cfg))
    assert all(torch.equal(a, b) for a, b in zip(first, again, strict=True))
    torch.manual_seed(cfg.seed)  # the weights are those of the seed, as before the scope
    seeded = _weights(_new_model(cfg))
    assert all(torch.equal(a, b) for a, b in zip(first, seeded, strict=True))
    other = _weights(build_model(protocol_cfg("default", "", "", variant=variant,
                                              model="tipnet", seed=6)))
    assert not all(torch.equal(a, b) for a, b in zip(first, other, strict=True))
