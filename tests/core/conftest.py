"""Fixtures of tests/core: the bad-input tests' shared data (`bad_input_env.env`), and one torch
thread for every test here."""

import pytest
from bad_input_env import env  # noqa: F401  (a fixture)


@pytest.fixture(autouse=True)
def _one_torch_thread(one_torch_thread):
    """One torch thread for each test of tests/core (tiny models: threads only add overhead),
    the previous count restored after it. Set once for the whole session, it had slowed every
    later test's training (the study net's sanity check: 107 s instead of 64 on 2 cores)."""
