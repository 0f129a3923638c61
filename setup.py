"""Package layout that pyproject.toml cannot state: `sim_assets/` stays at the top of the
repository (docs/dataset-format.md) and is installed as package data, `vistac_sim/sim_assets/`
(`vistac_sim.assets` finds it in either place), and the fingertip segmenter's trained weights,
`vistac_learn/data/segmenter_weights.pt`. Everything else is in pyproject.toml."""

from setuptools import find_namespace_packages, find_packages, setup

CODE = ["vistac", "vistac.*", "vistac_sim", "vistac_sim.*", "vistac_learn", "vistac_learn.*"]
ASSETS = ["vistac_sim.sim_assets",
          *(f"vistac_sim.sim_assets.{p}" for p in find_namespace_packages("sim_assets"))]

setup(
    packages=[*find_packages(include=CODE), *ASSETS],
    package_dir={"vistac_sim.sim_assets": "sim_assets"},
    package_data={**{p: ["*"] for p in ASSETS}, "vistac_learn.data": ["segmenter_weights.pt"]},
)
