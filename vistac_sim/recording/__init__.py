"""Recordings: the simulated 50 Hz press/hold/release session of a configuration (`session`),
the RH8D/FTS-3 recording CSV layout (`layout`), and `vistac ingest`, which turns such recordings
(simulated or real) plus their images into a dataset (`ingest`, no MuJoCo needed)."""
