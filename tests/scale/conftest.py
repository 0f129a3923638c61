"""Fixtures of the scale-out tests: a small local Ray instance per test module."""

from __future__ import annotations

import pytest

from vistac.engine import EngineCfg, ray_session

RAY_CPUS = 2


@pytest.fixture(scope="module")
def ray_local():
    """Ray started by `ray_session` (2 CPUs, a small object store, no dashboard), shut down after
    the module; the code under test finds it initialised and uses it."""
    with ray_session(EngineCfg(engine="ray"), num_cpus=RAY_CPUS) as ray:
        assert ray.cluster_resources()["CPU"] == RAY_CPUS
        yield ray
    assert not ray.is_initialized()
