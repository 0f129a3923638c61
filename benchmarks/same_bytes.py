"""Does a change leave the datasets alone? Generate with this tree and with another source tree
(same options, same seed) and compare every file byte for byte; the manifests are compared
without their run-dependent fields (wall time, workers, versions).

Writes `benchmarks/results/same_bytes.md` (or `--results`).

    python benchmarks/same_bytes.py --before-src SRC [--n 300] [--change TEXT] [--results FILE]
        [-- --preset lab --recordings]
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent
RUN_FIELDS = ("wall_time_s", "workers", "versions")


def generate(src: Path, out: Path, n: int, extra: list[str]) -> None:
    env = {**os.environ, "PYTHONPATH": str(src)}
    subprocess.run([sys.executable, "-m", "vistac.cli", "generate", "--out", str(out), "--n",
                    str(n), "--no-progress", *extra], env=env, cwd=src, check=True,
                   stdout=subprocess.DEVNULL)


def digests(root: Path) -> dict[str, str]:
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file() and p.name != "manifest.json"}


def manifest(root: Path) -> dict:
    m = json.loads((root / "manifest.json").read_text())
    return {k: v for k, v in m.items() if k not in RUN_FIELDS}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--before-src", type=Path, required=True)
    p.add_argument("--n", type=int, default=300)
    p.add_argument("--change", default="issue 22's simulator changes (session memory, "
                   "friction-aware sampling, resume checks)",
                   help="what the before tree lacks (written into the results)")
    p.add_argument("--results", type=Path, default=ROOT / "results" / "same_bytes.md")
    p.add_argument("extra", nargs="*", help="more generate options (after --)")
    args = p.parse_args(argv)
    work = Path(tempfile.mkdtemp(prefix="same_bytes_"))
    extra = args.extra or ["--preset", "lab", "--recordings", "--workers", "2"]
    generate(ROOT.parent, work / "now", args.n, extra)
    generate(args.before_src.resolve(), work / "before", args.n, extra)
    a, b = digests(work / "now"), digests(work / "before")
    differ = sorted(k for k in set(a) | set(b) if a.get(k) != b.get(k))
    same_manifest = manifest(work / "now") == manifest(work / "before")
    lines = ["# Same bytes before and after", "",
             f"`vistac generate --n {args.n} {' '.join(extra)}` with this tree and with the "
             f"tree before {args.change}. Command: `python benchmarks/same_bytes.py "
             f"--before-src SRC --n {args.n} -- {' '.join(extra)}`.", "",
             f"- files compared: {len(a)} (tables, images, recordings)",
             f"- files that differ: {len(differ)}" + (f" ({', '.join(differ[:5])})"
                                                      if differ else ""),
             f"- manifests equal without {', '.join(RUN_FIELDS)}: {same_manifest}", ""]
    args.results.write_text("\n".join(lines))
    print("\n".join(lines))
    return 0 if not differ and same_manifest else 1


if __name__ == "__main__":
    raise SystemExit(main())
