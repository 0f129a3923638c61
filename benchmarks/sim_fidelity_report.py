"""The report of `sim_fidelity.py`: CSV, Markdown (table, fronts, verdict) and a Pareto PNG."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pandas as pd

from vistac.provenance import provenance


def error_column(panel: str) -> str:
    return "p95_box_error_mm" if panel == "image size" else "error_deg"


def pareto(points: list[tuple[float, float]]) -> list[bool]:
    """Whether each (time, error) point is on the front: no other point is at least as good in
    both and better in one."""
    front = []
    for i, (t, e) in enumerate(points):
        dominated = any((t2 <= t and e2 <= e and (t2 < t or e2 < e))
                        for j, (t2, e2) in enumerate(points) if j != i)
        front.append(not dominated)
    return front


def mark_fronts(df: pd.DataFrame) -> pd.DataFrame:
    df = df.copy()
    df["on_front"] = False
    for panel, part in df.groupby("panel", sort=False):
        part = part[~part["reference"]]
        col = error_column(panel)
        flags = pareto(list(zip(part["s_per_sample"], part[col].fillna(math.inf), strict=True)))
        df.loc[part.index, "on_front"] = flags
    return df


def write_report(rows: list[dict], out: Path, meta: dict) -> None:
    out.mkdir(parents=True, exist_ok=True)
    df = mark_fronts(pd.DataFrame(rows))
    df.to_csv(out / "sim_fidelity.csv", index=False, float_format="%.6g")
    (out / "sim_fidelity.json").write_text(json.dumps({**meta, "provenance": provenance()},
                                                      indent=2) + "\n")
    lines = ["# Simulator accuracy against time", "",
             f"{meta['configs']} grasp configurations (of `--n {meta['n']}`, seed {meta['seed']}), "
             f"defaults {meta['defaults']}; run time {meta['wall_s']:.0f} s. Command: "
             f"`python benchmarks/sim_fidelity.py --n {meta['n']}`. Errors are against the "
             "panel's reference; s/sample is CPU seconds of the work the knob changes.", ""]
    verdicts = []
    for panel, part in df.groupby("panel", sort=False):
        col = error_column(panel)
        lines += [f"## {panel}", "", "| setting | s/sample | " + _head(panel) +
                  " | default | on front |", "|---|---|" + "---|" * (len(_cols(panel)) + 2)]
        for _, r in part.iterrows():
            cells = " | ".join(_fmt(r.get(c)) for c in _cols(panel))
            lines.append(f"| {r['setting']}{' (reference)' if r['reference'] else ''} | "
                         f"{r['s_per_sample']:.2e} | {cells} | {'**yes**' if r['default'] else ''}"
                         f" | {'yes' if r['on_front'] else ''} |")
        d = part[part["default"]]
        if len(d):
            ok = bool(d["on_front"].iloc[0])
            verdicts.append(f"- {panel}: the default ({d['setting'].iloc[0]}) "
                            f"{'lies on' if ok else 'does NOT lie on'} the front "
                            f"(error axis: {col}).")
        lines.append("")
    lines += ["## Verdict", "", *verdicts, ""]
    (out / "sim_fidelity.md").write_text("\n".join(lines))
    plot(df, out / "sim_fidelity.png")


def _cols(panel: str) -> list[str]:
    if panel == "image size":
        return ["median_box_error_mm", "p95_box_error_mm"]
    return ["median_index_deg", "p95_index_deg", "median_thumb_deg", "p95_thumb_deg",
            "error_deg", "compared", "rejected_vs_ref"]


def _head(panel: str) -> str:
    if panel == "image size":
        return "median finger-box error mm | p95 mm"
    return ("median index deg | p95 index deg | median thumb deg | p95 thumb deg | error deg "
            "(worse p95, floor 0.01) | compared | rejected (vs ref, count as 180 deg)")


def _fmt(v) -> str:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return ""
    if isinstance(v, float):
        return f"{v:.3g}"
    return str(v)


def plot(df: pd.DataFrame, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = list(dict.fromkeys(df["panel"]))
    fig, axes = plt.subplots(1, len(panels), figsize=(4.6 * len(panels), 4.2), squeeze=False)
    for ax, panel in zip(axes[0], panels, strict=True):
        part = df[(df["panel"] == panel) & ~df["reference"]]
        col = error_column(panel)
        y = part[col].clip(lower=1e-6)
        ax.scatter(part["s_per_sample"], y, c="0.6", s=18, label="setting")
        front = part[part["on_front"]].sort_values("s_per_sample")
        ax.plot(front["s_per_sample"], front[col].clip(lower=1e-6), "o-", color="C0", ms=5,
                label="Pareto front")
        d = part[part["default"]]
        ax.scatter(d["s_per_sample"], d[col].clip(lower=1e-6), marker="*", s=220, color="C3",
                   zorder=5, label="default")
        for _, r in part.iterrows():
            ax.annotate(r["setting"].split(" (")[0], (r["s_per_sample"], max(r[col], 1e-6)),
                        fontsize=5, alpha=0.7)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("CPU s per sample")
        ax.set_ylabel("p95 finger-box error, mm" if panel == "image size"
                      else "label error, deg (worse finger's p95)")
        ax.set_title(panel)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
