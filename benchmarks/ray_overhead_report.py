"""The report of `ray_overhead.py`: the CSV of every measured quantity and a Markdown page."""

from __future__ import annotations

import csv
import os
from pathlib import Path


def write_results(folder: Path, rows: list[tuple], md: str) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    with (folder / "ray_overhead.csv").open("w", newline="") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(["group", "quantity", "value", "unit"])
        w.writerows(rows)
    (folder / "ray_overhead.md").write_text(md)


def _fmt(x: float) -> str:
    return f"{x:.3g}" if abs(x) < 100 else f"{x:.0f}"


ENGINE_NAMES = {"local": "local (process pool)", "ray": "ray, driver writes (default)",
                "ray_workers": "ray, workers write (`--ray-writes workers`)"}


def markdown(args, cold, noop, runs, med, modes, cost, full, est, chunk_size, chunks) -> str:
    lo = med["local"]
    lines = [
        "# Ray overhead: `vistac generate` local vs Ray, and an estimate for 8 machines",
        "",
        f"`python benchmarks/ray_overhead.py --n {args.n} --workers {args.workers} --repeats "
        f"{args.repeats}` on {os.cpu_count()} CPU cores shared with other jobs (read CPU time; "
        f"wall time depends on the load). {chunks:.0f} chunks (one object each, at most "
        f"{chunk_size} configurations); medians of {args.repeats} interleaved runs of each "
        f"engine, each repeat on its own seed; one warm local Ray instance of {args.workers} "
        "CPUs for all Ray runs.",
        "",
        "| engine | wall s | cfg/s | CPU s | CPU / local | driver CPU s | worker CPU s "
        "| Ray daemons CPU s |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for name, m in med.items():
        lines.append(f"| {ENGINE_NAMES[name]} | {m['wall']:.1f} | {args.n / m['wall']:.1f} | "
                     f"{m['cpu']:.1f} | **{m['cpu'] / lo['cpu']:.2f}** | {m['driver']:.1f} | "
                     f"{m['pool'] + m['workers']:.1f} | {m['daemons']:.1f} |")
    lines += [
        "",
        "The Ray workers stay up between runs (imports and the GL context done once); the local "
        "pool starts and imports afresh in every run, so on a warm cluster Ray can cost less "
        "CPU than the local engine at this size (the first Ray run pays the workers' imports). "
        "CPU s of each run, in order: "
        + "; ".join(f"{e} " + ", ".join(f"{r['cpu']:.1f}" for r in rs) for e, rs in runs.items())
        + ".",
        "",
        "## Per-task overhead (no-op tasks, warm workers)",
        "",
        "| how | wall ms/task | CPU ms/task |",
        "|---|---|---|",
        f"| all submitted at once | {noop['batch_wall_ms']:.2f} | {noop['batch_cpu_ms']:.2f} |",
        f"| one round trip at a time | {noop['roundtrip_wall_ms']:.2f} | "
        f"{noop['roundtrip_cpu_ms']:.2f} |",
        f"| `RayRunner`, {args.workers} in flight (generate's path) | "
        f"{noop['runner_wall_ms']:.2f} | {noop['runner_cpu_ms']:.2f} |",
        "",
        f"Cold start of a local instance (start, one task, shut down): {cold:.1f} s, paid once "
        "per command without `--ray-address`.",
        "",
        "## Per configuration and per chunk",
        "",
        f"- worker CPU per configuration (Ray's daemons included), making it: "
        f"{1e3 * modes['driver writes']['worker_cpu_s']:.1f} ms (the runs with the driver "
        "writing); a worker that also writes it adds the driver's writing cost below;",
        f"- the driver, for one full chunk of {full['configurations']} (measured directly, "
        f"CPU): unpickling it {1e3 * full['receive_s']:.1f} ms, writing its images and shards "
        f"{1e3 * full['commit_s']:.1f} ms, plus a whole no-op task through `RayRunner` "
        f"{1e3 * full['task_s']:.1f} ms (an upper bound of the driver's share): "
        f"**{1e3 * modes['driver writes']['driver_s']:.2f} ms per configuration** when it "
        f"writes, **{1e3 * modes['workers write']['driver_s']:.2f} ms** when the workers do. "
        f"(In the runs above, chunks of {args.n / chunks:.0f} on average, the writing driver "
        f"used {1e3 * cost['extra_cpu_s']:.2f} ms CPU per configuration more than the local "
        "engine's parent process.)",
        f"- data per configuration: {modes['driver writes']['bytes'] / 1e3:.1f} kB (to the "
        "driver, or to the shared filesystem).",
        "",
        f"## On paper: {args.cores_per_machine}-core machines, {args.gbit:g} Gbit/s links",
        "",
        "Configurations per second = the least of what the workers make (cores / worker CPU "
        "per configuration), what the one driver handles (1 / its CPU per configuration) and "
        "what the link the data crosses carries (bandwidth / bytes per configuration: the "
        "driver's, or the file server's). Speed-up: against one such machine running the local "
        "engine at the same CPU per configuration, making and writing (a long run amortises "
        "the local pool's start-up).",
        "",
        "| machines | cores | writes | workers bound | driver bound | network bound "
        "| estimate cfg/s | limited by | speed-up |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for i in range(len(est["driver writes"])):
        for mode in est:
            r = est[mode][i]
            lines.append(f"| {r['machines']} | {r['cores']} | {mode} | "
                         f"{_fmt(r['workers_cfg_s'])} | {_fmt(r['driver_cfg_s'])} | "
                         f"{_fmt(r['network_cfg_s'])} | **{_fmt(r['cfg_s'])}** | {r['bound']} "
                         f"| {r['speedup']:.1f}x |")
    return "\n".join(lines) + "\n"
