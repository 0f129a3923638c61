"""The report of `generate_vs_bare.py`: JSON, a Markdown table and a PNG.

`write_report` saves the run as ``generate_vs_bare.json`` (or ``generate_vs_bare_<label>.json``
for a labelled run such as ``before``), then writes ``generate_vs_bare.md`` and
``generate_vs_bare.png`` from the unlabelled run, with the ``before`` run beside it when saved.
"""

from __future__ import annotations

import json
from pathlib import Path

from vistac.provenance import provenance


def write_report(result: dict, folder: Path) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    label = result.get("label") or ""
    name = f"generate_vs_bare_{label}.json" if label else "generate_vs_bare.json"
    result = {**result, "provenance": provenance()}
    (folder / name).write_text(json.dumps(result, indent=2) + "\n")
    now_file = folder / "generate_vs_bare.json"
    before_file = folder / "generate_vs_bare_before.json"
    if not now_file.exists():
        return
    now = json.loads(now_file.read_text())
    before = json.loads(before_file.read_text()) if before_file.exists() else None
    (folder / "generate_vs_bare.md").write_text(markdown(now, before))
    plot(now, before, folder / "generate_vs_bare.png")


def markdown(now: dict, before: dict | None) -> str:
    runs = [("before", before), ("now", now)] if before else [("now", now)]
    lines = [
        "# `vistac generate` against a bare MuJoCo loop",
        "",
        f"{now['n']} configurations, {now['workers']} processes, {now['cpu_count']} CPU cores "
        "(shared with other jobs: the pairs are interleaved and the medians compared). Command: "
        "`python benchmarks/generate_vs_bare.py --n {n} --workers {w}`.".format(
            n=now["n"], w=now["workers"]),
        "",
        "| run | bare loop s | generate s | generate / bare (wall) | bare CPU s | generate CPU s "
        "| generate / bare (CPU) | bare cfg/s | generate cfg/s | pairs (bare, generate) wall s |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for name, r in runs:
        lines.append(f"| {name} | {r['bare_loop_s']} | {r['generate_s']} | "
                     f"**{r['ratio_generate_over_bare']}** | {r['bare_loop_cpu_s']} | "
                     f"{r['generate_cpu_s']} | **{r['cpu_ratio_generate_over_bare']}** | "
                     f"{r['bare_samples_per_s']} | {r['generate_samples_per_s']} | "
                     f"{r['pairs_s']} |")
    lines += ["", f"## Where the time goes (ms per configuration, one process, cProfile, "
              f"n = {now['profile_n']})", "",
              "A part is the cumulative time of the functions doing it; cProfile inflates "
              "Python-heavy parts more than MuJoCo's C calls, so read the split, not the sum, "
              "against the ratio above.", ""]
    head = ["part"] + [f"generate ({n})" for n, _ in runs] + [f"bare ({n})" for n, _ in runs]
    lines += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    keys = list(now["breakdown_ms_per_sample"]["generate"])
    for k in keys:
        cells = [r["breakdown_ms_per_sample"]["generate"].get(k, "") for _, r in runs]
        cells += [r["breakdown_ms_per_sample"]["bare"].get(k, "") for _, r in runs]
        lines.append(f"| {k} | " + " | ".join(str(c) for c in cells) + " |")
    lines += ["", "## Per-configuration cost and memory against the number of configurations",
              "", "Each size is one `vistac generate` run in a fresh interpreter (start-up and "
              "the final tables included); peak RSS is the largest resident set of any one of "
              "its processes.", ""]
    for name, r in runs:
        lines += [f"**{name}**", "", "| configurations | wall s | wall ms per configuration | "
                  "CPU ms per configuration | peak RSS MiB |", "|---|---|---|---|---|"]
        lines += [f"| {s['n']} | {s['wall_s']} | {s['ms_per_config']} | "
                  f"{s.get('cpu_ms_per_config', '')} | {s['peak_rss_mib']} |"
                  for s in r["scaling"]]
        lines.append("")
    return "\n".join(lines) + "\n"


def plot(now: dict, before: dict | None, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    runs = [("before", before), ("now", now)] if before else [("now", now)]
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(13, 6.5))
    keys = list(now["breakdown_ms_per_sample"]["generate"])[1:]
    bars = [(f"generate {n}", r["breakdown_ms_per_sample"]["generate"]) for n, r in runs]
    bars += [(f"bare {n}", r["breakdown_ms_per_sample"]["bare"]) for n, r in runs]
    cmap = plt.get_cmap("tab20")
    for i, (_, parts) in enumerate(bars):
        left = 0.0
        for j, k in enumerate(keys):
            v = max(parts.get(k, 0.0), 0.0)
            ax1.barh(i, v, left=left, color=cmap(j % 20), label=k if i == 0 else None)
            left += v
    ax1.set_yticks(range(len(bars)), [b for b, _ in bars])
    ax1.set_xlabel("ms per configuration (one process, cProfile)")
    ax1.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=3)  # below
    for name, r in runs:
        ns = [s["n"] for s in r["scaling"]]
        ax2.plot(ns, [s["ms_per_config"] for s in r["scaling"]], "o-", label=f"wall ms {name}")
        ax2.plot(ns, [s["cpu_ms_per_config"] for s in r["scaling"]], "^:",
                 label=f"CPU ms {name}")
    ax2.set_xscale("log")
    ax2.set_xlabel("configurations")
    ax2.set_ylabel("ms per configuration")
    twin = ax2.twinx()
    for name, r in runs:
        twin.plot([s["n"] for s in r["scaling"]], [s["peak_rss_mib"] for s in r["scaling"]],
                  "s--", alpha=0.6, label=f"peak RSS {name}")
    twin.set_ylabel("peak RSS of the largest process, MiB")
    ax2.legend(loc="upper left", fontsize=8)
    twin.legend(loc="upper right", fontsize=8)
    ax2.set_title(f"generate / bare at n={now['n']} (wall, CPU): " + ", ".join(
        f"{n} {r['ratio_generate_over_bare']}, {r['cpu_ratio_generate_over_bare']}"
        for n, r in runs), fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
