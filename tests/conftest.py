"""Shared test set-up: the --runslow switch and a small generated dataset.

Tests mirror the packages: `core/` (vistac: config, dataset, CLI, imports), `sim/`
(vistac_sim), `learn/` (vistac_learn). Helpers live next to them (`learn_fixtures.py` here,
`sim/hard_cases.py`); pytest puts each test's folder and this one on the import path.
"""

from __future__ import annotations

import pytest


def pytest_addoption(parser):
    parser.addoption("--runslow", action="store_true", default=False, help="run slow tests")


def pytest_collection_modifyitems(config, items):
    if config.getoption("--runslow"):
        return
    skip = pytest.mark.skip(reason="slow: run with --runslow")
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(skip)


@pytest.fixture
def one_torch_thread():
    """One torch thread for a test (tiny models: threads only add overhead on a shared CPU),
    the previous count restored after it."""
    import torch

    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


@pytest.fixture(scope="session")
def small_dataset(tmp_path_factory):
    """A real 24-configuration dataset made by `vistac.generate` (in-process, one worker)."""
    import vistac
    from vistac_sim.objects.config import ObjectsCfg

    cfg = vistac.GenerateCfg.from_preset(noise=0.05, n=24, seed=1, chunk_size=5,
                                         objects=ObjectsCfg(n_objects=8))
    return vistac.generate(cfg, tmp_path_factory.mktemp("data") / "d", workers=1).path
