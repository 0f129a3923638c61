"""Paths of the simulator's assets (`sim_assets/`), built from the package location.

The folder is package data: an installed vistac carries it as ``vistac_sim/sim_assets``; a
source checkout (editable install) has it at the top of the repository. Never the working
directory.
"""

from pathlib import Path


def _root() -> Path:
    package = Path(__file__).resolve().parent
    for root in (package / "sim_assets", package.parent / "sim_assets"):
        if (root / "hand" / "scene.xml").is_file():
            return root
    raise RuntimeError(f"sim_assets not found next to {package}: reinstall vistac")


ROOT = _root()
SCENE_XML = ROOT / "hand" / "scene.xml"  # table, camera, object body; includes hand.xml
HAND_XML = ROOT / "hand" / "hand.xml"  # the two-finger hand on its own
EXAMPLE_MESHES = ROOT / "meshes"
