"""Paths of the project's assets, built from the package location and checked to exist."""

from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent / "sim_assets"
EXAMPLE_MESHES = ROOT / "meshes"

assert ROOT.is_dir(), f"sim_assets not found at {ROOT}: install vistac from a source checkout"
