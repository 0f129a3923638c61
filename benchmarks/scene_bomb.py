"""How fast hostile scene files are refused and how long their error lines are (issue 22: a YAML
alias bomb ran 40 s into a MemoryError; an error line could echo a 10 MB value).

Each file is given to `vistac generate --scene` in a fresh process; the figures are the wall time
to the refusal and the length of the one stderr line. Writes `benchmarks/results/scene_bomb.md`.

    python benchmarks/scene_bomb.py
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent


def bomb(levels: int) -> str:
    """Ten items, each level ten aliases of the one below: 10^levels values once expanded."""
    names = "abcdefghijklmnop"[:levels]
    text = f"{names[0]}: &{names[0]} [" + ", ".join(["x"] * 10) + "]\n"
    for p, c in zip(names, names[1:], strict=False):
        text += f"{c}: &{c} [" + ", ".join([f"*{p}"] * 10) + "]\n"
    return text + f"effects: {{noise: *{names[-1]}}}\n"


FILES = {
    "alias bomb, 10^9 values": bomb(9),
    "alias bomb, 10^12 values": bomb(12),
    "10 MB value (a file over the 1 MiB limit)": "effects: {noise: '" + "x" * 10_000_000 + "'}\n",
    "900 kB value": "effects: {noise: '" + "x" * 900_000 + "'}\n",
    "recursive alias": "effects: &a {noise: *a}\n",
}


def main(argv: list[str] | None = None) -> int:
    argparse.ArgumentParser(description=__doc__.splitlines()[0]).parse_args(argv)
    work = Path(tempfile.mkdtemp(prefix="scene_bomb_"))
    lines = ["# Hostile scene files: time to refusal, error line length", "",
             "`vistac generate --out D --n 2 --scene FILE` in a fresh process (start-up "
             "included). Shared machine. Command: `python benchmarks/scene_bomb.py`.", "",
             "| file | exit status | seconds | error line, characters |", "|---|---|---|---|"]
    for i, (name, text) in enumerate(FILES.items()):
        f = work / f"scene_{i}.yaml"
        f.write_text(text)
        t0 = time.perf_counter()
        r = subprocess.run([sys.executable, "-m", "vistac.cli", "generate", "--out",
                            str(work / "out"), "--n", "2", "--scene", str(f)],
                           capture_output=True, text=True, cwd=ROOT.parent)
        wall = time.perf_counter() - t0
        err = r.stderr.strip().splitlines()
        lines.append(f"| {name} | {r.returncode} | {wall:.1f} | "
                     f"{len(err[0]) if len(err) == 1 else f'{len(err)} lines'} |")
        print(lines[-1], flush=True)
    (ROOT / "results" / "scene_bomb.md").write_text("\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
