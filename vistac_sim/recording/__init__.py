"""Recordings: the simulated 50 Hz press/hold/release session of a configuration (`session`)
and its recording CSV (`layout`), in the RH8D/FTS-3 layout of `vistac.dataset.recordings`.
`vistac ingest`, which reads such recordings back, is `vistac.dataset.ingest` (no MuJoCo)."""
