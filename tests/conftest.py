"""Shared test set-up: the --runslow switch and a small generated dataset."""

from __future__ import annotations

import os

os.environ.setdefault("MUJOCO_GL", "egl")  # before anything imports mujoco

import pytest  # noqa: E402


def pytest_addoption(parser):
    parser.addoption("--runslow", action="store_true", default=False, help="run slow tests")


def pytest_collection_modifyitems(config, items):
    if config.getoption("--runslow"):
        return
    skip = pytest.mark.skip(reason="slow: run with --runslow")
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(skip)


@pytest.fixture(scope="session")
def small_dataset(tmp_path_factory):
    """A real 24-configuration dataset made by `vistac generate` (in-process, one worker)."""
    from vistac_sim.cli import main

    out = tmp_path_factory.mktemp("data") / "d"
    rc = main(["generate", "--n", "24", "--noise", "0.05", "--seed", "1", "--out", str(out),
               "--workers", "1", "--no-progress", "--n-objects", "8", "--chunk-size", "5"])
    assert rc == 0
    return out
