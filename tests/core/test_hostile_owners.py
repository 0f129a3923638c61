"""Nothing a user owns is overwritten (issue 31): every writing command refuses, before any
write, a folder of another kind (dataset, run, tuning, experiment, evaluation) or a non-empty
folder of somebody else's files, naming what it found; ``--resume`` never turns one kind of
folder into another; the one-writer lock follows the real folder through a symbolic link.

Each row runs `vistac.cli.main` in-process and asserts exit status 2, exactly one line on stderr
naming what is wrong, no traceback, every file of the folder byte for byte as it was, and then a
good command that proves the folder still works (the run still evaluates, ...).
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pytest
from bad_input_env import EVAL_OK, GEN_OK, ING_OK, TRAIN_OK

from vistac.cli import main
from vistac.errors import UserError
from vistac.folder_kinds import MARKER, folder_kind
from vistac.folder_lock import hold

T, E, G, I = TRAIN_OK, EVAL_OK, GEN_OK, ING_OK  # noqa: E741
TUNE = "tune --data {data} --out {out} --trials 1 --epochs 1 --size 16 --quiet"
NOISE = ("experiment label-noise --data {data} --out {out} --levels 0 --seeds 1 --epochs 1 "
         "--size 16 --quiet")
EVAL_RUN = "evaluate --run {out} --no-plots --no-references"  # the run still scores


# ------------------------------------------------------------------------ folders to start from
def a_run(env, out: Path) -> None:
    shutil.copytree(env["paths"]["run"], out)


def a_run_with_damaged_config(env, out: Path) -> None:
    a_run(env, out)
    (out / "config.json").write_bytes((out / "config.json").read_bytes()[:40])


def a_dataset(env, out: Path) -> None:
    shutil.copytree(env["paths"]["data2"], out)


def a_tuning(env, out: Path) -> None:
    """What `vistac tune` leaves: its settings and its trials table."""
    out.mkdir(parents=True)
    (out / "config.json").write_text(json.dumps({"base": {"lr": 0.01}, "space": {},
                                                 "tune": {"seed": 0, "trials": 1}}))
    (out / "trials.csv").write_text("trial,status,objective\n0,ok,1.5\n")


def an_experiment(env, out: Path) -> None:
    """What `vistac experiment label-noise` leaves: its settings and its cells."""
    out.mkdir(parents=True)
    (out / "config.json").write_text(json.dumps({"experiment": "label_noise", "settings": {},
                                                 "train": {}}))
    (out / "cells.csv").write_text("level,seed,status\n0,1,ok\n")


def users_scores(env, out: Path) -> None:
    """A user's own folder of results, with the names evaluate writes."""
    out.mkdir(parents=True)
    (out / "metrics.json").write_text('{"accuracy": 0.93}\n')
    (out / "predictions.parquet").write_bytes(b"PAR1 my own predictions PAR1")


def users_notes(env, out: Path) -> None:
    out.mkdir(parents=True)
    (out / "notes.txt").write_text("mine")


@dataclass
class Case:
    """A command into a folder that is not its to write: its arguments, the text of its one
    error line, what {out} holds first, and a command that then still works."""

    id: str
    argv: str
    needle: str
    setup: Callable
    good: str | None = None


CASES = [
    Case("tune-resume-into-a-run", TUNE + " --resume", "holds a run (config.json), not a tuning",
         a_run, EVAL_RUN),
    Case("tune-into-a-run", TUNE, "holds a run", a_run, EVAL_RUN),
    Case("tune-resume-into-a-run-damaged-config", TUNE + " --resume",
         "holds a run (checkpoints)", a_run_with_damaged_config),
    Case("train-into-an-experiment", T, "holds an experiment (config.json), not a run",
         an_experiment),
    Case("train-resume-into-an-experiment", T + " --resume", "holds an experiment",
         an_experiment),
    Case("train-resume-into-a-tuning", T + " --resume", "holds a tuning", a_tuning),
    Case("train-into-a-dataset", T, "holds a dataset (manifest.json), not a run", a_dataset,
         T.replace("{out}", "{out}/../fresh-run")),
    Case("experiment-into-a-run", NOISE, "holds a run (config.json), not an experiment", a_run,
         EVAL_RUN),
    Case("experiment-into-a-tuning", NOISE, "holds a tuning", a_tuning),
    Case("generate-into-a-run", G, "holds a run", a_run, EVAL_RUN),
    Case("generate-resume-into-a-tuning", G + " --resume", "holds a tuning", a_tuning),
    Case("ingest-into-an-experiment", I, "holds an experiment", an_experiment),
    Case("evaluate-out-a-run", E.replace("{run}", "{out}"), "holds a run (config.json), not an "
         "evaluation", a_run, EVAL_RUN),
    Case("evaluate-out-a-dataset", E, "holds a dataset", a_dataset),
    Case("evaluate-out-users-scores", E, "not empty and holds no evaluation (it holds "
         "metrics.json, predictions.parquet)", users_scores),
    Case("evaluate-out-users-notes", E, "holds no evaluation (it holds notes.txt)", users_notes),
    Case("tune-into-users-notes", TUNE, "not empty", users_notes),
    Case("experiment-into-users-notes", NOISE, "not empty", users_notes),
]


def _snapshot(out: Path) -> dict[str, str]:
    """Every file under `out` (relative path -> hash of its bytes), and every folder."""
    return {str(p.relative_to(out)): hashlib.sha256(p.read_bytes()).hexdigest()
            if p.is_file() else "folder" for p in out.rglob("*")}


def _argv(template: str, env, out: Path) -> list[str]:
    return template.format(out=out, **env["paths"]).split()


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_a_folder_of_another_kind_is_refused(case: Case, env, capsys):
    out = env["root"] / "owners" / case.id / "out"
    case.setup(env, out)
    before = _snapshot(out)
    capsys.readouterr()
    rc = main(_argv(case.argv, env, out))
    err = capsys.readouterr().err
    assert rc == 2 and "Traceback" not in err, err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("vistac"), err
    assert case.needle in lines[0] and str(out) in lines[0], lines[0]
    assert _snapshot(out) == before  # nothing written, nothing lost
    if case.good:
        assert main(_argv(case.good, env, out)) == 0, f"{case.good!r} failed after {case.id}"
    capsys.readouterr()


def test_kinds_are_read_from_what_each_command_wrote(env):
    paths = env["paths"]
    assert folder_kind(paths["data"]) == ("dataset", "manifest.json")
    assert folder_kind(paths["run"]) == ("run", "config.json")
    assert folder_kind(paths["partial"]) == ("dataset", ".partial")
    assert folder_kind(paths["missing"]) is None


def test_evaluate_marks_its_folder_and_scores_into_it_again(env, capsys):
    """An evaluation's folder says so before its first file (and a refused evaluation leaves
    none); a second evaluation into it (its own) works, while a user's file beside it is
    kept."""
    out = env["root"] / "owners" / "evaluation"
    argv = _argv(E, env, out)
    assert main(argv) == 0
    assert (out / MARKER).read_text() == "evaluation\n"
    assert folder_kind(out) == ("evaluation", MARKER)
    (out / "my-notes.txt").write_text("mine")
    assert main(argv) == 0
    assert (out / "my-notes.txt").read_text() == "mine"
    (out / MARKER).unlink()  # an evaluation written before the marker: known by metrics.json
    assert folder_kind(out) == ("evaluation", "metrics.json")
    assert main(_argv(T, env, out)) == 2
    assert "holds an evaluation (metrics.json), not a run" in capsys.readouterr().err


def test_evaluate_writes_whole_files_or_none(env, monkeypatch, capsys):
    """A write that fails half-way (a full disk) leaves the previous predictions whole and no
    temporary behind, in one line naming the file; the rerun works."""
    import pyarrow.parquet as pq

    from vistac.dataset import files

    out = env["root"] / "owners" / "torn"
    argv = _argv(E, env, out)
    assert main(argv) == 0
    before = (out / "predictions.parquet").read_bytes()
    real_open = open

    class FullDisk:  # writes the first bytes, then the disk is full
        def __init__(self, fh):
            self.fh = fh

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            self.fh.close()

        def write(self, data):
            self.fh.write(bytes(data)[:10])
            raise OSError(28, "No space left on device")

    def full_disk_open(path, mode="r", *args, **kwargs):
        fh = real_open(path, mode, *args, **kwargs)
        return FullDisk(fh) if "predictions.parquet" in str(path) else fh

    monkeypatch.setattr(files, "open", full_disk_open, raising=False)
    capsys.readouterr()
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "Traceback" not in err, err
    assert "predictions.parquet: cannot be written: No space left on device; free some space" \
        in err, err
    monkeypatch.undo()
    assert (out / "predictions.parquet").read_bytes() == before
    pq.read_table(out / "predictions.parquet")
    assert not list(out.glob(".*.tmp"))
    assert main(argv) == 0


def test_the_lock_follows_a_symlink_between_two_processes(tmp_path):
    """One process holds folder `x`; a second, given a symbolic link to `x` (and a path with
    ``..``), is refused, naming the holder; free once the first ends."""
    real, link = tmp_path / "x", tmp_path / "link"
    real.mkdir()
    link.symlink_to(real, target_is_directory=True)
    code = ("import sys\nfrom vistac.folder_lock import hold\n"
            "with hold(sys.argv[1], 'first'):\n    print('held', flush=True)\n"
            "    sys.stdin.readline()\n")
    proc = subprocess.Popen([sys.executable, "-c", code, str(real)], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline().strip() == "held"
        for name in (link, tmp_path / "sub" / ".." / "link"):
            (tmp_path / "sub").mkdir(exist_ok=True)
            with pytest.raises(UserError, match=rf"in use by pid {proc.pid} on .*'first'"):
                with hold(name, "second"):
                    pass
    finally:
        proc.stdin.close()
        proc.wait(timeout=60)
    with hold(link, "second"):
        pass
    assert not [p for p in os.listdir(tmp_path) if p.endswith(".lock")]


def test_a_tuning_resumes_from_another_working_directory(env, tmp_path, monkeypatch):
    """A tuning's settings record absolute paths: resumed from another directory, with paths
    relative to it, it is the same tuning (it used to say "other base settings (data, out)");
    another dataset still is not. A tuning recorded with relative paths resumes from where it
    was started, as before."""
    import vistac
    from vistac_learn.tune import driver
    from vistac_learn.tune.space import load_space

    data = Path(env["paths"]["data"])
    (tmp_path / "a" / "deep").mkdir(parents=True)
    shutil.copytree(data, tmp_path / "data")

    def check(cwd: Path, data_path: str, out_path: str, resume: bool) -> None:
        monkeypatch.chdir(cwd)
        base = vistac.TrainCfg(data=data_path, out=out_path)
        cfg = driver.TuneCfg(out=out_path, trials=1)
        driver.check_folder(cfg, base, load_space(None), resume)
        if not resume:
            Path(out_path).mkdir()
            driver.atomic_write_json(Path(out_path) / "config.json",
                                     driver._meta(cfg, base, load_space(None)))

    check(tmp_path / "a", "../data", "tune", resume=False)
    check(tmp_path / "a" / "deep", "../../data", "../tune", resume=True)
    check(tmp_path, "data", "a/tune", resume=True)
    with pytest.raises(UserError, match=r"--resume with other base settings \(data\)"):
        check(tmp_path, str(data), "a/tune", resume=True)
