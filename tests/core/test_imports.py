"""What each part imports: the core and the learner never load MuJoCo, `vistac generate` and
`vistac ingest` never load torch, and MuJoCo enters the simulator through one module."""

from __future__ import annotations

import pkgutil
import re
import subprocess
import sys
from pathlib import Path

import vistac
import vistac.dataset.ingest
import vistac_learn
import vistac_sim

ROOT = Path(vistac.__file__).resolve().parent.parent


def _modules(package) -> list[str]:
    return [package.__name__] + [m.name for m in pkgutil.walk_packages(package.__path__,
                                                                       package.__name__ + ".")]


def _loaded_after(code: str) -> set[str]:
    """Top-level modules loaded by a fresh interpreter running `code`."""
    probe = code + "\nimport sys\nprint(' '.join(sorted({m.split('.')[0] for m in sys.modules})))"
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                         check=True, cwd=ROOT)
    return set(out.stdout.split())


def test_core_imports_neither_mujoco_nor_torch():
    loaded = _loaded_after("\n".join(f"import {m}" for m in _modules(vistac)))
    assert "vistac" in loaded and not {"mujoco", "torch"} & loaded


def test_learner_does_not_import_mujoco():
    loaded = _loaded_after("\n".join(f"import {m}" for m in _modules(vistac_learn)))
    assert "torch" in loaded and "mujoco" not in loaded


def test_ingest_imports_neither_the_simulator_nor_torch():
    loaded = _loaded_after("\n".join(f"import {m}" for m in _modules(vistac.dataset.ingest)))
    assert "vistac" in loaded and not {"mujoco", "torch", "vistac_sim"} & loaded


def test_ingest_package_leaves_the_api_function_in_place():
    """Importing the `ingest` package (as the CLI does) must not hide `vistac.ingest(...)`."""
    code = ("import vistac\nf = vistac.ingest\nimport vistac.dataset.ingest.command\n"
            "assert vistac.ingest is f and callable(vistac.ingest)")
    assert "vistac" in _loaded_after(code)


def test_generate_does_not_import_torch(tmp_path):
    argv = ["generate", "--out", str(tmp_path / "d"), "--n", "2", "--n-objects", "1",
            "--repeats", "1", "--workers", "1", "--no-progress"]
    code = f"from vistac.cli import main\nassert main({argv!r}) == 0"
    loaded = _loaded_after(code)
    assert "mujoco" in loaded and "torch" not in loaded


def test_mujoco_enters_the_simulator_through_one_module():
    package = Path(vistac_sim.__file__).parent
    for path in [*package.rglob("*.py"), *Path(vistac.__file__).parent.rglob("*.py"),
                 *Path(vistac_learn.__file__).parent.rglob("*.py")]:
        text = path.read_text()
        if path == package / "mj.py":
            assert "MUJOCO_GL" in text and re.search(r"^\s*import mujoco", text, re.M)
            continue
        assert not re.search(r"^\s*(import mujoco|from mujoco)", text, re.M), path
        assert "MUJOCO_GL" not in text, path
