"""Real meshes at `--friction 0`: does every mesh that gives labels at the default friction give
them without friction too, and how many draws does a configuration cost (issue 22)?

The meshes are those of `mesh_collection.py` (the `pybullet_data` meshes of the pybullet wheel
and the derived low, open and broken-on-purpose variants). Each mesh gets one `generate` run of
`--n` configurations (1 repeat) at friction 0, with the tree at hand and, with `--before-src`,
with a tree from before the friction-aware sampler. Per mesh: its status, configurations,
redraws by reason, and the acceptance of the press (configurations over configurations plus the
draws the press or its checks rejected: what a MuJoCo solve buys).

Writes `benchmarks/results/frictionless_meshes.csv` and `.md`.

    python benchmarks/frictionless_meshes.py [--n 12] [--wheel pybullet-....whl]
        [--before-src SRC] [--work DIR]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import warnings
from pathlib import Path

import pandas as pd

ROOT = Path(__file__).resolve().parent
SAMPLER_REASONS = {"unreachable", "no_opposing_thumb", "fingers_overlap"}


def run_tree(files: list[Path], n: int, work: Path) -> list[dict]:
    """One friction-0 run per mesh with the vistac on the path; its rows."""
    import shutil

    from vistac.errors import UserError
    from vistac_sim.generate.config import GenerateCfg
    from vistac_sim.generate.run import generate
    from vistac_sim.objects.config import ObjectsCfg
    from vistac_sim.physics.config import PhysicsCfg

    rows = []
    for f in files:
        out = work / f.stem
        shutil.rmtree(out, ignore_errors=True)
        row = {"mesh": f"{f.parent.name}/{f.name}", "status": "", "configurations": 0,
               "rejections": "{}", "press_acceptance": None}
        try:
            cfg = GenerateCfg(n=n, repeats=1, objects=ObjectsCfg(paths=(str(f),)),
                              physics=PhysicsCfg(friction=0.0))
            manifest = generate(cfg, out, workers=1, progress=False)
            obj = manifest["per_object"][0]
            rej = obj["rejections"]
            solved = sum(v for k, v in rej.items() if k not in SAMPLER_REASONS)
            configs = manifest["counts"]["configs"]
            row.update(status=obj["status"], configurations=configs,
                       rejections=json.dumps(rej),
                       press_acceptance=round(configs / (configs + solved), 3) if configs else 0)
        except UserError as exc:
            row.update(status="refused", rejections=str(exc).split(": ")[-1][:80])
        rows.append(row)
        print(json.dumps(row), flush=True)
    return rows


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--n", type=int, default=12, help="configurations per mesh")
    p.add_argument("--wheel", default=None, help="the pybullet wheel (else pip download)")
    p.add_argument("--work", type=Path, default=None)
    p.add_argument("--before-src", type=Path, default=None)
    p.add_argument("--tree-run", action="store_true", help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    warnings.simplefilter("ignore")
    work = (args.work or Path(tempfile.mkdtemp(prefix="frictionless_meshes_"))).resolve()
    os.environ.setdefault("VISTAC_CACHE", str(work / "vistac_cache"))
    from mesh_collection import derived, fetch_pybullet

    files = fetch_pybullet(work, args.wheel) + derived(work / "derived")
    files = [f for f in files if not f.name.startswith("broken_")]
    if args.tree_run:  # a child: this tree's rows as JSON lines
        run_tree(files, args.n, work / "runs" / Path(os.environ["PYTHONPATH"]).name)
        return 0
    tables = []
    trees = [("now", ROOT.parent)] + ([("before", args.before_src.resolve())]
                                      if args.before_src else [])
    for name, src in trees:
        cmd = [sys.executable, str(Path(__file__).resolve()), "--tree-run", "--n", str(args.n),
               "--work", str(work)] + (["--wheel", args.wheel] if args.wheel else [])
        env = {**os.environ, "PYTHONPATH": str(src)}
        text = subprocess.run(cmd, env=env, cwd=src, check=True, capture_output=True,
                              text=True).stdout
        rows = [json.loads(line) for line in text.splitlines() if line.startswith("{")]
        tables.append(pd.DataFrame(rows).set_index("mesh").add_prefix(f"{name}_"))
    table = pd.concat(tables, axis=1).reset_index()
    default = pd.read_csv(ROOT / "results" / "mesh_collection.csv")[["mesh", "status"]]
    table = table.merge(default.rename(columns={"status": "default_friction_status"}),
                        on="mesh", how="left")
    out = ROOT / "results"
    table.to_csv(out / "frictionless_meshes.csv", index=False)
    write_report(out / "frictionless_meshes.md", table, args)
    print(f"wrote {out / 'frictionless_meshes.csv'} and .md")
    return 0


def write_report(path: Path, table: pd.DataFrame, args) -> None:
    lines = ["# Real meshes at friction 0", "",
             f"One `generate` run per mesh, {args.n} configurations, 1 repeat, `--friction 0`. "
             "`default_friction_status`: the mesh's status at the default friction "
             "(`mesh_collection.csv`). press_acceptance: configurations / (configurations + "
             "draws the press or its checks rejected). Command: `python "
             f"benchmarks/frictionless_meshes.py --n {args.n}"
             + (" --before-src SRC` (SRC: the tree before the friction-aware sampler)."
                if args.before_src else "`."), ""]
    for tree in ("now", "before"):
        if f"{tree}_status" in table:
            used = (table[f"{tree}_status"] == "used").sum()
            acc = table[f"{tree}_press_acceptance"].astype(float)
            lines.append(f"- {tree}: {used} of {len(table)} meshes give labels, "
                         f"{int(table[f'{tree}_configurations'].sum())} configurations, median "
                         f"press acceptance {acc.median():.2f} (lowest {acc.min():.2f})")
    lines += ["", "| " + " | ".join(table.columns) + " |", "|" + "---|" * len(table.columns)]
    cells = table.astype(object).where(table.notna(), "").astype(str)
    lines += ["| " + " | ".join(c.replace("|", "/") for c in r) + " |"
              for r in cells.values.tolist()]
    path.write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    raise SystemExit(main())
