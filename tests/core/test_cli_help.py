"""The CLI says what it does (issue 33): every option of every command comes from a typed
config and `--help` shows its default and range; one name for "no progress"; no progress bar
frames in a log; every `--option` the README and docs/ name exists in its command's `--help`."""

from __future__ import annotations

import argparse
import io
import re
import subprocess
import sys
from pathlib import Path

import pytest

import vistac
from vistac.cli import COMMANDS, build_parser
from vistac.progress import LineProgress, bar

ROOT = Path(vistac.__file__).resolve().parent.parent


def _subparsers(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(action.choices)


def command_parsers() -> dict[str, argparse.ArgumentParser]:
    """'generate' -> its parser, ...; a command with sub-commands gives 'experiment sim2real'."""
    out = {}
    for name in COMMANDS:
        parser = _subparsers(build_parser([name]))[name]
        if any(isinstance(a, argparse._SubParsersAction) for a in parser._actions):
            out |= {f"{name} {k}": p for k, p in _subparsers(parser).items()}
        else:
            out[name] = parser
    return out


def _options(parser: argparse.ArgumentParser) -> list[argparse.Action]:
    return [a for a in parser._actions if a.option_strings and a.help != argparse.SUPPRESS
            and not isinstance(a, argparse._HelpAction)]


@pytest.fixture(scope="module")
def parsers() -> dict[str, argparse.ArgumentParser]:
    return command_parsers()


def test_every_option_comes_from_a_typed_config(parsers):
    """`add_options` marks what it declares (its range, maybe none): no plain argparse flags."""
    plain = [f"{name} {a.option_strings[0]}" for name, p in parsers.items()
             for a in _options(p) if not hasattr(a, "allowed")]
    assert plain == []


def test_help_shows_each_default_and_range(parsers):
    missing = []
    for name, parser in parsers.items():
        for a in _options(parser):
            shown = parser._get_formatter()._expand_help(a)  # what --help prints, unwrapped
            if a.allowed and a.allowed not in shown:
                missing.append(f"{name} {a.option_strings[0]}: no {a.allowed}")
            if getattr(a, "default_text", None) and "default:" not in shown:
                missing.append(f"{name} {a.option_strings[0]}: no default")
    assert missing == []
    train = " ".join(parsers["train"].format_help().split())
    assert "(default: 25, --protocol study: 20; range: [1, 100000])" in train
    assert "--mirror, --no-mirror mirror half" in train and "(default: on, --protocol study: off)" \
        in train
    assert "range: [0, 4294967296)" in train  # --seed: lt is an open end


def test_no_progress_is_one_name_and_quiet_a_hidden_alias(parsers):
    for name in ("generate", "train", "evaluate", "tune", "experiment sim2real",
                 "experiment label-noise", "demo"):
        parser = parsers[name]
        assert "--no-progress" in parser.format_help()
        assert "--quiet" not in parser.format_help()
    args = build_parser(["train"]).parse_args(["train", "--data", "d", "--out", "o", "--quiet"])
    assert args.no_progress is True


def test_progress_without_a_terminal_is_plain_lines(monkeypatch):
    err = io.StringIO()  # not a terminal
    monkeypatch.setattr(sys, "stderr", err)
    b = bar(total=3, desc="generate", unit="cfg", lines="each")
    assert isinstance(b, LineProgress)
    for _ in range(3):
        b.update(1)
    b.close()
    assert list(bar(range(4), desc="images", unit="img")) == [0, 1, 2, 3]  # one line at the end
    for bars in (bar(range(5), enabled=False), bar(range(5), leave=False)):  # no line
        assert list(bars) == [0, 1, 2, 3, 4]
    lines = err.getvalue().splitlines()
    assert [x.split(",")[0] for x in lines] == ["generate: 1/3 cfg", "generate: 2/3 cfg",
                                                 "generate: 3/3 cfg", "images: 4/4 img"]
    assert "\r" not in err.getvalue()


def test_a_log_of_generate_has_lines_not_bar_frames(tmp_path):
    """`vistac generate ... 2> log`: one line per chunk, no carriage-return frames."""
    log = tmp_path / "log"
    with log.open("w") as f:
        subprocess.run([sys.executable, "-m", "vistac.cli", "generate", "--out",
                        str(tmp_path / "d"), "--n", "4", "--image-size", "32", "--n-objects", "1",
                        "--repeats", "1", "--workers", "1", "--chunk-size", "2"],
                       stderr=f, stdout=subprocess.DEVNULL, check=True, timeout=120)
    text = log.read_text()
    assert "\r" not in text
    assert [x.split(",")[0] for x in text.splitlines() if x.startswith("generate:")] == \
        ["generate: 2/4 cfg", "generate: 4/4 cfg"]


# --------------------------------------------------------------- options named in the docs
def _commands_in_docs() -> list[tuple[str, str]]:
    """(file, command line) for each `vistac COMMAND ...` in a code block or code span of the
    README and docs/ (continued lines joined, cut at a pipe, ;, && or #)."""
    found = []
    for doc in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        text = doc.read_text()
        blocks = re.findall(r"^```[^\n]*\n(.*?)^```", text, re.S | re.M)
        prose = re.sub(r"^```[^\n]*\n.*?^```", "", text, flags=re.S | re.M)
        pieces = [line for b in blocks for line in b.replace("\\\n", " ").splitlines()]
        pieces += re.findall(r"`([^`\n]+)`", prose)
        for piece in pieces:
            for m in re.finditer(r"\bvistac ([a-z][a-z0-9-]*)([^|;&#]*)", piece):
                found.append((doc.name, f"{m.group(1)}{m.group(2)}"))
    return found


def test_every_option_named_in_the_docs_exists(parsers):
    unknown, lines = [], _commands_in_docs()
    assert len(lines) > 20  # the README's examples were found
    for doc, line in lines:
        words = line.split()
        name = words[0]
        if name not in COMMANDS:
            continue
        if f"{name} {words[1] if len(words) > 1 else ''}" in parsers:
            name = f"{name} {words[1]}"
        elif name not in parsers:  # a command with sub-commands, none named
            continue
        known = {s for a in parsers[name]._actions for s in a.option_strings}
        unknown += [f"{doc}: vistac {name} {w}" for w in re.findall(r"(?<![\w-])--[a-z][\w-]*",
                                                                    line) if w not in known]
    assert unknown == []
