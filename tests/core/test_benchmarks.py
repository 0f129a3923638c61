"""The README's reproduction commands: every benchmark script it cites answers `--help`, and every
results file that the README, docs/ and benchmarks/README.md name exists."""

from __future__ import annotations

import json
import os
import re
import runpy
import subprocess
import sys
from pathlib import Path

import pytest

import vistac

ROOT = Path(vistac.__file__).resolve().parent.parent
BENCH = ROOT / "benchmarks"
RESULTS = BENCH / "results"
PAGES = [ROOT / "README.md", BENCH / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def cited_scripts() -> list[str]:
    """The benchmark scripts of the README's commands (``python benchmarks/NAME.py``)."""
    return sorted(set(re.findall(r"python benchmarks/([a-z0-9_]+)\.py",
                              (ROOT / "README.md").read_text())))


def named_results() -> dict[str, set[Path]]:
    """Results files each page names: ``benchmarks/results/X`` anywhere (``X.{md,json}`` expanded),
    and on benchmarks/README.md also the bare names of its tables (``X.md``, ``X.{md,json}``)."""
    out: dict[str, set[Path]] = {}
    for page in PAGES:
        text = page.read_text()
        found = set()
        spelled = re.findall(r"benchmarks/results/([\w./-]+?)(?:\.\{([a-z,]+)\})?(?=[`)\s,;:]|$)",
                             text)
        if page == BENCH / "README.md":
            spelled += re.findall(
                r"`([a-z0-9_]+(?:\.(?:md|json|png|csv|jpg))?)(?:\.\{([a-z,]+)\})?`", text)
        for stem, exts in spelled:
            stem = stem.rstrip(".")
            if exts:
                found |= {RESULTS / f"{stem}.{e}" for e in exts.split(",")}
            elif "." in Path(stem).name or stem.endswith("/") or (RESULTS / stem).is_dir():
                found.add(RESULTS / stem)
        out[str(page.relative_to(ROOT))] = found
    return out


def test_the_readme_cites_benchmark_scripts_that_exist():
    scripts = cited_scripts()
    assert len(scripts) >= 5
    assert [s for s in scripts if not (BENCH / f"{s}.py").is_file()] == []


def test_every_cited_benchmark_script_answers_help(monkeypatch, capsys):
    """Each script run as ``python benchmarks/NAME.py --help`` runs it (its own folder first on
    the path), in this process: the shared imports are paid once."""
    monkeypatch.syspath_prepend(str(BENCH))
    failed = {}
    for name in cited_scripts():
        monkeypatch.setattr(sys, "argv", [str(BENCH / f"{name}.py"), "--help"])
        try:
            runpy.run_path(str(BENCH / f"{name}.py"), run_name="__main__")
            failed[name] = "no exit"
        except SystemExit as exc:
            if exc.code not in (0, None):
                failed[name] = f"exit {exc.code}"
        except Exception as exc:  # an import that fails, say
            failed[name] = repr(exc)
        out = capsys.readouterr().out
        if name not in failed and "usage:" not in out:
            failed[name] = "no usage line"
    assert failed == {}


@pytest.mark.slow
def test_every_cited_benchmark_script_answers_help_in_a_fresh_process():
    """As a reader runs them: one fresh process each, nothing on the path but the script's
    folder."""
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    failed = {}
    for name in cited_scripts():
        out = subprocess.run([sys.executable, str(BENCH / f"{name}.py"), "--help"], cwd=ROOT,
                             env=env, capture_output=True, text=True, timeout=300)
        if out.returncode != 0 or "usage:" not in out.stdout:
            failed[name] = out.stderr[-500:]
    assert failed == {}


def test_every_named_results_file_exists():
    named = named_results()
    assert len(named["README.md"]) >= 5 and len(named["benchmarks/README.md"]) >= 20
    missing = {page: sorted(str(p.relative_to(ROOT)) for p in files if not p.exists())
               for page, files in named.items()}
    assert {k: v for k, v in missing.items() if v} == {}


def test_no_results_file_carries_a_version_suffix():
    assert [p.name for p in RESULTS.rglob("*") if re.search(r"_v\d+(\W|_|$)", p.name)] == []


def test_relative_links_of_the_readme_the_index_and_the_changelog_resolve():
    broken = []
    for page in (ROOT / "README.md", BENCH / "README.md", ROOT / "CHANGELOG.md"):
        for target in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", page.read_text()):
            if not re.match(r"[a-z]+://", target) and not (page.parent / target).exists():
                broken.append(f"{page.relative_to(ROOT)}: {target}")
    assert broken == []


def test_every_results_json_records_its_command_and_commit():
    """A reader can reproduce every committed results file: its JSON names the command that made
    it and the commit of the code (vistac.provenance, or recorded after the fact for older ones)."""
    missing = []
    for path in sorted((ROOT / "benchmarks" / "results").rglob("*.json")):
        data = json.loads(path.read_text())
        prov = data.get("provenance", {}) if isinstance(data, dict) else {}
        if not (prov.get("command") and prov.get("commit")):
            missing.append(path.name)
    assert missing == []


def test_a_checkout_is_dirty_by_its_code_not_by_the_benchmarks_own_results(tmp_path,
                                                                           monkeypatch):
    """`provenance.dirty`: a changed tracked file counts, a changed results file does not (a
    benchmark rewriting its own results must not call its checkout dirty)."""
    import subprocess

    from vistac import provenance

    def git(*args):
        subprocess.run(["git", "-C", str(tmp_path), *args], check=True, capture_output=True)

    (tmp_path / "benchmarks" / "results").mkdir(parents=True)
    (tmp_path / "code.py").write_text("x = 1\n")
    (tmp_path / "benchmarks" / "results" / "r.json").write_text("{}\n")
    git("init", "-q")
    git("add", "-A")
    git("-c", "user.name=t", "-c", "user.email=t@t", "commit", "-qm", "init")
    monkeypatch.setattr(provenance, "REPO", tmp_path)
    assert provenance.git_state()[1] is False
    (tmp_path / "benchmarks" / "results" / "r.json").write_text('{"a": 1}\n')
    assert provenance.git_state()[1] is False
    (tmp_path / "code.py").write_text("x = 2\n")
    assert provenance.git_state()[1] is True
