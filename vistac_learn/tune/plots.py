"""The convergence figure of a tuning: each trial's objective and the best so far."""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def plot_convergence(rows: list[dict], path: Path) -> None:
    """Objective per trial (dots; diverged trials as crosses at the top) and the best so far.

    Args:
        rows: Finished trials in trial order (``trial``, ``objective``; NaN when diverged).
        path: PNG to write.
    """
    trials = [r["trial"] + 1 for r in rows]
    obj = [r["objective"] for r in rows]
    best, cur = [], math.inf
    for v in obj:
        cur = min(cur, v) if math.isfinite(v) else cur
        best.append(cur if math.isfinite(cur) else math.nan)
    fig, ax = plt.subplots(figsize=(5.5, 3.5), dpi=120)
    ok = [(t, v) for t, v in zip(trials, obj, strict=True) if math.isfinite(v)]
    if ok:
        ax.plot(*zip(*ok, strict=True), "o", color="0.6", ms=4, label="trial")
        top = max(v for _, v in ok)
        bad = [t for t, v in zip(trials, obj, strict=True) if not math.isfinite(v)]
        if bad:
            ax.plot(bad, [top] * len(bad), "x", color="tab:red", label="diverged")
    ax.step(trials, best, where="post", color="tab:blue", label="best so far")
    ax.set_xlabel("trial")
    ax.set_ylabel("validation median angle (deg)")
    ax.set_title("vistac tune: convergence")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    tmp = path.with_name(f".{path.name}.tmp.png")
    fig.savefig(tmp)
    plt.close(fig)
    tmp.replace(path)
