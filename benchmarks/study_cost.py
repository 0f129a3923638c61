"""What the study's answers cost: accuracy against training CPU seconds for every trained row of
the study-twin benchmarks (issue "The study's table replayed", part 3), the study's nets and
the project's default recipe side by side.

No training: reads the committed results of ``study_replay.py`` (162 configurations, the
study's protocol) and ``study_curve.py`` (162 to 5000 configurations), and any of
``study_label_noise.py``, ``study_sim2real.py`` that exist, and plots the index finger's
% in cone and median angle to the cone mean against each row's training CPU seconds (user +
system, mean over seeds). The twin's constant predictor (a net that learnt nothing) and noise
floor from the replay are drawn as lines. The replay and the curve use two datasets of the
same twin (1300 and 7200 configurations); their references differ by a point or less.

Usage:
    .venv/bin/python benchmarks/study_cost.py
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from study_replay import RESULTS  # noqa: E402

from vistac.provenance import provenance  # noqa: E402

ANGLE = "angle_to_mean_median_deg"
KEYS = ("correct_y_pct", "in_cone_pct", ANGLE)
SOURCES = ("study_replay", "study_curve", "study_label_noise", "study_sim2real")


def family(label: str) -> str:
    """The net a row trained: the study's V3, SmallConv, the project's default recipe or that
    recipe without mirroring and contact targets."""
    low = label.lower()
    if "v3" in low:
        return "SchoeConv100-V3(FC160), study protocol"
    if "smallconv" in low:
        return "SmallConv, study protocol"
    if "no mirror" in low:
        return "default recipe, no mirror, no contact targets"
    return "default recipe"


def gather(results: Path) -> tuple[list[dict], list[dict], list[str]]:
    """Every trained row with a training CPU time, the replay's references, the files read."""
    rows, refs, read = [], [], []
    for name in SOURCES:
        path = results / f"{name}.json"
        if not path.exists():
            continue
        read.append(path.name)
        data = json.loads(path.read_text())
        for r in data.get("rows", []):
            s = r.get("summary", {})
            if r.get("kind") == "reference" and name == "study_replay":
                refs.append({"label": r["label"], **{k: s[k]["mean"] for k in KEYS}})
            if r.get("kind") != "model" or not s.get("train_cpu_s"):
                continue
            size = r.get("size") or (r.get("runs") or [{}])[0].get("n_train")
            rows.append({"source": name, "label": r["label"], "family": family(r["label"]),
                         "size": size, "seeds": s.get("n_seeds"),
                         "train_cpu_s": s["train_cpu_s"],
                         **{k: s[k]["mean"] for k in KEYS},
                         **{f"{k}_std": s[k]["std"] for k in KEYS}})
    return rows, refs, read


def table(rows: list[dict], refs: list[dict]) -> str:
    """A markdown table of the rows, cheapest first, and the references."""
    lines = ["| source | row | train configs | seeds | train CPU s | % correct y | % in cone | "
             "median angle to mean (deg) |", "|---|---|---|---|---|---|---|---|"]
    for r in sorted(rows, key=lambda r: r["train_cpu_s"]):
        lines.append(f"| {r['source']} | {r['label']} | {r['size'] or '-'} | {r['seeds']} | "
                     f"{r['train_cpu_s']:.0f} | {r['correct_y_pct']:.1f} | "
                     f"{r['in_cone_pct']:.1f} ± {r['in_cone_pct_std']:.1f} | "
                     f"{r[ANGLE]:.2f} ± {r[ANGLE + '_std']:.2f} |")
    for r in refs:
        lines.append(f"| study_replay | {r['label']} | - | - | 0 | {r['correct_y_pct']:.1f} | "
                     f"{r['in_cone_pct']:.1f} | {r[ANGLE]:.2f} |")
    return "\n".join(lines)


def plot(rows: list[dict], refs: list[dict], path: Path) -> None:
    """% in cone and the median angle against training CPU seconds (log), a marker per source,
    a colour per net; the references as horizontal lines."""
    colours = {"SchoeConv100-V3(FC160), study protocol": "tab:blue",
               "SmallConv, study protocol": "tab:orange", "default recipe": "tab:green",
               "default recipe, no mirror, no contact targets": "tab:purple"}
    markers = dict(zip(SOURCES, ("*", "o", "s", "^"), strict=True))
    fig, axes = plt.subplots(1, 2, figsize=(12, 5.4))
    for ax, key in zip(axes, ("in_cone_pct", ANGLE), strict=True):
        for fam, colour in colours.items():
            for source, marker in markers.items():
                mine = sorted((r for r in rows if r["family"] == fam and r["source"] == source),
                              key=lambda r: r["train_cpu_s"])
                if not mine:
                    continue
                ax.errorbar([r["train_cpu_s"] for r in mine], [r[key] for r in mine],
                            yerr=[r[f"{key}_std"] for r in mine], fmt=marker + "-",
                            ms=10 if marker == "*" else 6, capsize=3, color=colour,
                            label=f"{fam} ({source})")
                for r in mine:
                    if r["size"]:
                        ax.annotate(str(r["size"]), (r["train_cpu_s"], r[key]), fontsize=7,
                                    textcoords="offset points", xytext=(4, 4))
        for ref, style in zip(refs, ("--", ":", "-."), strict=False):
            ax.axhline(ref[key], ls=style, lw=1, color="grey", label=ref["label"])
        ax.set_xscale("log")
        ax.set_xlabel("training CPU seconds (user + system; numbers: training configurations)")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("% in cone (index, test)")
    axes[1].set_ylabel("median angle to the cone mean (deg, index)")
    fig.legend(*axes[0].get_legend_handles_labels(), fontsize=7, loc="lower center", ncol=3)
    fig.suptitle("The study's nets and the project's recipe on the twin: accuracy against "
                 "training CPU time", fontsize=10)
    fig.tight_layout(rect=(0, 0.16, 1, 1))
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    """Command-line entry."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    p.add_argument("--results", default=str(RESULTS),
                   help="folder of the study benchmarks' results; <name>.json|md|png go there")
    p.add_argument("--name", default="study_cost", help="results file name")
    args = p.parse_args(argv)
    results = Path(args.results)
    rows, refs, read = gather(results)
    if not rows:
        print(f"error: no trained rows with CPU times in {results} "
              f"(looked for {', '.join(s + '.json' for s in SOURCES)})", file=sys.stderr)
        return 2
    note = ("Index finger, test splits of the twin (`sim_assets/scenes/study.yaml`). Read from "
            f"{', '.join(read)}; each row's recipe and datasets are in its own file. Training CPU "
            "seconds: user + system, mean over seeds; runs on one thread each and on two "
            "threads mixed (one thread does the same work for about a quarter less CPU).")
    md = table(rows, refs)
    (results / f"{args.name}.json").write_text(json.dumps(
        {"provenance": provenance(), "read": read, "rows": rows, "references": refs,
         "table": md, "note": note}, indent=2) + "\n")
    (results / f"{args.name}.md").write_text("# What the study's answers cost: accuracy against "
                                             f"training CPU time\n\n{md}\n\n{note}\n")
    plot(rows, refs, results / f"{args.name}.png")
    print(md)
    return 0


if __name__ == "__main__":
    sys.exit(main())
