"""A regular (non-editable) install carries every package and `sim_assets/` as package data."""

from __future__ import annotations

import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

import vistac

ROOT = Path(vistac.__file__).resolve().parent.parent


@pytest.mark.slow
def test_wheel_holds_every_package_and_the_assets(tmp_path):
    if not (ROOT / ".git").exists():
        pytest.skip("needs the source checkout")
    files = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True,
                           check=True).stdout.split()
    src = tmp_path / "src"
    for name in files:  # a clean copy: the wheel is built from the tracked files only
        (src / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(ROOT / name, src / name)
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation",
                    "-q", "-w", str(tmp_path / "wheel"), str(src)], check=True)
    (wheel,) = (tmp_path / "wheel").glob("vistac-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    packages = {str(p.relative_to(src)) for p in src.rglob("__init__.py")
                if p.parts[len(src.parts)] in ("vistac", "vistac_sim", "vistac_learn")}
    assert packages <= names
    assets = {f"vistac_sim/{name}" for name in files if name.startswith("sim_assets/")}
    assert {"vistac_sim/sim_assets/hand/scene.xml", "vistac_sim/sim_assets/hand/hand.xml"} \
        <= assets <= names
