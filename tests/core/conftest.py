"""Fixtures of tests/core: the bad-input tests' shared data (`bad_input_env.env`)."""

from bad_input_env import env  # noqa: F401  (a fixture)
