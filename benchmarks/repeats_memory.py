"""Peak memory of `vistac generate` against `--repeats` (issue 22: it grew with the square).

Each run is one configuration of the lab preset (its sensor effects simulate the whole session
of K presses) in one process (`--workers 1`), optionally with `--recordings`; the figure is the
process's peak resident set (`ru_maxrss`). With `--before-src` (a source tree from before, e.g.
`git archive 47798a8 | tar -x -C SRC`) the same runs use that tree for the repeats given by
`--before-repeats` (it took 9.4 GiB at 3000: keep them small on a shared machine).

Writes `benchmarks/results/repeats_memory.csv` and `.md`.

    python benchmarks/repeats_memory.py --before-src SRC --recordings no
    python benchmarks/repeats_memory.py --repeats 3000 10000 --recordings yes --append
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pandas as pd

ROOT = Path(__file__).resolve().parent
REPO = ROOT.parent
RUN = """
import resource, subprocess, sys
rc = subprocess.run(sys.argv[1:], stdout=subprocess.DEVNULL).returncode
print(rc, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)
"""


def peak_mib(repeats: int, recordings: bool, src: Path, work: Path) -> tuple[float, float]:
    """(peak RSS in MiB, wall seconds) of one generate run with the tree at `src`."""
    out = work / f"{src.name}_{repeats}_{int(recordings)}"
    argv = [sys.executable, "-m", "vistac.cli", "generate", "--out", str(out), "--n", "1",
            "--repeats", str(repeats), "--preset", "lab", "--n-objects", "1", "--image-size",
            "64", "--workers", "1", "--no-progress"] + (["--recordings"] if recordings else [])
    env = {**os.environ, "PYTHONPATH": str(src)}
    t0 = time.perf_counter()
    text = subprocess.run([sys.executable, "-c", RUN, *argv], env=env, cwd=src, check=True,
                          capture_output=True, text=True).stdout.split()
    if text[0] != "0":
        raise RuntimeError(f"generate failed at --repeats {repeats} ({src})")
    return int(text[1]) / 1024, time.perf_counter() - t0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeats", type=int, nargs="+", default=[300, 1000, 3000])
    p.add_argument("--before-src", type=Path, default=None)
    p.add_argument("--before-repeats", type=int, nargs="+", default=[300, 1000])
    p.add_argument("--recordings", choices=("no", "yes", "both"), default="both",
                   help="runs without, with, or both")
    p.add_argument("--append", action="store_true", help="add to the results of an earlier run")
    args = p.parse_args(argv)
    with_rec = {"no": (False,), "yes": (True,), "both": (False, True)}[args.recordings]
    work = Path(tempfile.mkdtemp(prefix="repeats_memory_"))
    rows = []
    trees = [("now", REPO, args.repeats)]
    if args.before_src:
        trees.append(("before", args.before_src.resolve(), args.before_repeats))
    for tree, src, repeats in trees:
        for k in repeats:
            for rec in with_rec:
                mib, wall = peak_mib(k, rec, src, work)
                rows.append({"tree": tree, "repeats": k, "recordings": rec,
                             "peak_rss_mib": round(mib), "wall_s": round(wall, 1)})
                print(rows[-1], flush=True)
    out = ROOT / "results"
    table = pd.DataFrame(rows)
    if args.append and (out / "repeats_memory.csv").exists():
        table = pd.concat([pd.read_csv(out / "repeats_memory.csv"), table], ignore_index=True)
    table.to_csv(out / "repeats_memory.csv", index=False)
    lines = ["# Peak memory of `vistac generate` against `--repeats`", "",
             "One configuration, lab preset, 64 px, one process; peak resident set of the "
             "process. Shared 2-core machine (other jobs running): the wall times are noisy, the "
             "memory is not. Commands: `python benchmarks/repeats_memory.py --before-src SRC "
             "--recordings no` (SRC: the tree before issue 22's fix), then `python "
             "benchmarks/repeats_memory.py --repeats 3000 10000 --recordings yes --append`. "
             "Before: the issue measured 9.4 GiB at 3000 repeats (not rerun here: the machine "
             "is shared).", "",
             "| tree | repeats | recordings | peak RSS MiB | wall s |", "|---|---|---|---|---|"]
    lines += [f"| {r.tree} | {r.repeats} | {'yes' if r.recordings else 'no'} | "
              f"{r.peak_rss_mib} | {r.wall_s} |" for r in table.itertuples()]
    (out / "repeats_memory.md").write_text("\n".join(lines) + "\n")
    print(f"wrote {out / 'repeats_memory.csv'} and .md")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
