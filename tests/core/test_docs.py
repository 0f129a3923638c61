"""The documentation lives in the repository: nothing points outside it, docs/ links resolve,
and the README's Python API example runs."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

import vistac

ROOT = Path(vistac.__file__).resolve().parent.parent
TEXT = (".py", ".md", ".toml", ".xml", ".yaml", ".yml", ".cfg", ".txt")
SKIP = {".venv", ".git", "build", "dist", "runs", "data", "__pycache__", ".pytest_cache"}
# spelled in pieces so that this file does not match itself
OUTSIDE = re.compile("|".join([r"shared/" + "spec", r"\.\./" + "shared", r"contracts\." + "md",
                               r"thesis\." + "md"]))


def _files() -> list[Path]:
    out = []
    for folder, dirs, names in os.walk(ROOT):
        dirs[:] = [d for d in dirs if d not in SKIP and not d.endswith(".egg-info")]
        out += [Path(folder) / n for n in names
                if Path(n).suffix in TEXT or n in ("Makefile", "run")]
    return out


def test_nothing_in_the_repository_refers_to_files_outside_it():
    hits = [f"{p.relative_to(ROOT)}:{i}" for p in _files()
            for i, line in enumerate(p.read_text(errors="replace").splitlines(), 1)
            if OUTSIDE.search(line)]
    assert hits == []


def test_relative_links_of_the_docs_resolve():
    docs = sorted((ROOT / "docs").glob("*.md"))
    assert {"dataset-format.md", "study.md", "physics.md", "results.md"} <= {d.name for d in docs}
    broken = []
    for doc in docs:
        for target in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", doc.read_text()):
            if not re.match(r"[a-z]+://", target) and not (doc.parent / target).exists():
                broken.append(f"{doc.name}: {target}")
    assert broken == []


def readme_example() -> str:
    """The Python block of the README's section on the Python API."""
    text = (ROOT / "README.md").read_text()
    section = text[text.index("## The Python API"):]
    return re.search(r"```python\n(.*?)```", section, re.S).group(1)


def test_readme_example_uses_the_api_names():
    code = readme_example()
    for name in re.findall(r"vistac\.(\w+)", code):
        assert hasattr(vistac, name), name


@pytest.mark.slow
def test_readme_example_runs(tmp_path):
    (tmp_path / "example.py").write_text(readme_example())
    out = subprocess.run([sys.executable, "example.py"], cwd=tmp_path, capture_output=True,
                         text=True, timeout=900)
    assert out.returncode == 0, out.stderr[-2000:]
    assert "60 configurations, 360 presses" in out.stdout and "% in cone" in out.stdout
    assert (tmp_path / "runs/api-example/eval/test/metrics.json").is_file()
