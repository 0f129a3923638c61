"""What Ray costs on this machine, and what 8 machines would give: `vistac generate` local vs Ray.

Measured, on one machine, with one local Ray instance of `--workers` CPUs kept running for the
whole benchmark (a warm cluster, as a user joining one with ``--ray-address`` sees it):

1. **Generate throughput**: `--repeats` interleaved pairs of `generate(n, workers)` with the
   local engine (a process pool) and the Ray engine (one task per chunk), each pair on its own
   seed (so no run reuses another's scenes). Wall time and CPU time (user + system): the local
   run's own process and its waited-for pool; the Ray run's driver plus every process of the Ray
   instance (read from ``/proc``), split into driver, Ray workers and Ray's daemons.
2. **Per-task overhead**: no-op Ray tasks, (a) submitted all at once, (b) one round trip at a
   time, (c) through `RayRunner` as generate uses it (at most `workers` in flight): wall and CPU
   per task; and the cold start of a local instance (start, first task, shutdown).
3. **Per-chunk cost** of generate on Ray: the worker CPU per configuration (from 1.), and the
   driver's CPU for one full chunk (`--chunk-size` default), measured directly: unpickling what
   the task returns and committing it (the driver writes the images and shards), plus one
   no-op task through `RayRunner`; and the bytes a chunk ships.
4. **On paper, up to 8 machines**: configurations per second = the least of what the workers
   make (machines x cores / worker CPU per configuration), what the one driver receives and
   writes (1 / its CPU per configuration) and what its network link carries (bandwidth / bytes
   per configuration).

Writes ``results/ray_overhead.csv`` (group, quantity, value, unit) and ``ray_overhead.md``
(`ray_overhead_report.py`).

Usage:
    python benchmarks/ray_overhead.py --n 1000 --workers 2 --repeats 3
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import statistics
import sys
import time
from pathlib import Path

RESULTS = Path(__file__).parent / "results"
TICK = os.sysconf("SC_CLK_TCK")
RAY_AGENTS = ("ray::DashboardA", "ray::RuntimeEnv")  # Ray's daemons named like its workers


# ------------------------------------------------------------------------------- CPU clocks
def _proc_tree() -> dict[int, tuple[str, float]]:
    """pid -> (name, CPU seconds so far) of every live descendant of this process."""
    info: dict[int, tuple[int, str, float]] = {}
    for entry in os.scandir("/proc"):
        if not entry.name.isdigit():
            continue
        try:
            stat = Path(entry.path, "stat").read_text()
        except OSError:
            continue
        name, rest = stat[stat.index("(") + 1:stat.rindex(")")], stat[stat.rindex(")") + 2:]
        fields = rest.split()
        info[int(entry.name)] = (int(fields[1]), name, (int(fields[11]) + int(fields[12])) / TICK)
    me, tree, frontier = os.getpid(), {}, [os.getpid()]
    while frontier:
        parent = frontier.pop()
        for pid, (ppid, name, cpu) in info.items():
            if ppid == parent and pid != me and pid not in tree:
                tree[pid] = (name, cpu)
                frontier.append(pid)
    return tree


def _own_cpu() -> tuple[float, float]:
    """CPU seconds of this process and of its waited-for children."""
    s, c = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return s.ru_utime + s.ru_stime, c.ru_utime + c.ru_stime


class Clock:
    """Wall and CPU time of a block: this process, its waited children, its live descendants
    (split into Ray workers, named ``ray::IDLE`` or ``ray::<task>``, and everything else)."""

    def __enter__(self) -> Clock:
        self._tree, self._own, self._t = _proc_tree(), _own_cpu(), time.perf_counter()
        return self

    def __exit__(self, *exc) -> None:
        self.wall = time.perf_counter() - self._t
        own = _own_cpu()
        self.driver = own[0] - self._own[0]
        self.children = own[1] - self._own[1]
        self.workers = self.daemons = 0.0
        for pid, (name, cpu) in _proc_tree().items():
            delta = cpu - self._tree.get(pid, (name, 0.0))[1]
            if name.startswith("ray::") and not name.startswith(RAY_AGENTS):
                self.workers += delta
            else:
                self.daemons += delta

    @property
    def cpu(self) -> float:
        return self.driver + self.children + self.workers + self.daemons


# --------------------------------------------------------------------------- measurements
def _noop(x):
    return x


def generate_pairs(n: int, workers: int, repeats: int, out: Path) -> dict[str, list[dict]]:
    """`repeats` interleaved runs of generate: local, Ray with the driver writing, Ray with the
    workers writing; per run: wall, CPU parts, bytes, the driver's commits."""
    from vistac.engine import EngineCfg
    from vistac_sim.generate import on_ray
    from vistac_sim.generate.config import GenerateCfg
    from vistac_sim.generate.run import generate

    engines = {"local": EngineCfg(), "ray": EngineCfg(engine="ray"),
               "ray_workers": EngineCfg(engine="ray", ray_writes="workers")}
    runs: dict[str, list[dict]] = {e: [] for e in engines}
    commit = on_ray.commit_chunk
    for r in range(repeats):
        for k, engine in enumerate(engines):  # a seed per run: no run reuses a worker's scenes
            cfg = GenerateCfg(n=n, seed=100 + len(engines) * r + k)
            folder = out / f"{engine}_{r}"
            shutil.rmtree(folder, ignore_errors=True)
            committed: list[tuple[int, float]] = []  # (size, seconds) of the driver's commits

            def timed_commit(o, i, made, committed=committed):
                t0 = time.perf_counter()
                size = commit(o, i, made)
                committed.append((size, time.perf_counter() - t0))
                return size

            on_ray.commit_chunk = timed_commit
            with Clock() as clock:
                generate(cfg, folder, workers=workers, progress=False,
                         engine=engines[engine])
            if engine == "local":  # Ray's idle daemons are not the local engine's cost
                clock.workers = clock.daemons = 0.0
            size = sum(p.stat().st_size for p in folder.rglob("*") if p.is_file())
            runs[engine].append({"wall": clock.wall, "cpu": clock.cpu, "driver": clock.driver,
                                 "pool": clock.children, "workers": clock.workers,
                                 "daemons": clock.daemons, "bytes": size,
                                 "chunks": len(committed),
                                 "commit": sum(t for _, t in committed), "commits": committed})
            shutil.rmtree(folder)
            print(f"repeat {r} {engine}: {clock.wall:.1f} s wall, {clock.cpu:.1f} CPU s "
                  f"(driver {clock.driver:.1f}, workers {clock.workers + clock.children:.1f}, "
                  f"Ray daemons {clock.daemons:.1f})", flush=True)
    on_ray.commit_chunk = commit
    return runs


def noop_overhead(ray, workers: int, n_tasks: int) -> dict[str, float]:
    """Milliseconds of wall and CPU per no-op task, three ways."""
    from vistac.engine import RayRunner

    task = ray.remote(_noop).options(num_cpus=1)
    ray.get([task.remote(i) for i in range(4 * workers)])  # workers started and warm
    res = {}
    with Clock() as c:
        ray.get([task.remote(i) for i in range(n_tasks)])
    res |= {"batch_wall_ms": 1e3 * c.wall / n_tasks, "batch_cpu_ms": 1e3 * c.cpu / n_tasks}
    k = max(1, n_tasks // 5)
    with Clock() as c:
        for i in range(k):
            ray.get(task.remote(i))
    res |= {"roundtrip_wall_ms": 1e3 * c.wall / k, "roundtrip_cpu_ms": 1e3 * c.cpu / k}
    runner = RayRunner(ray, _noop, max_concurrent=workers)
    with Clock() as c:
        assert runner.map(range(n_tasks)) == list(range(n_tasks))
    res |= {"runner_wall_ms": 1e3 * c.wall / n_tasks, "runner_cpu_ms": 1e3 * c.cpu / n_tasks}
    return res


def driver_chunk_cost(chunk_size: int, repeats: int, out: Path) -> dict[str, float]:
    """CPU seconds the Ray driver spends on one full chunk, measured directly: unpickling what
    a task returns (Ray's serialiser is pickle 5) and committing it (images, shards)."""
    import pickle

    from vistac.config import apply
    from vistac.dataset.schema import IMAGES, PARTIAL
    from vistac_sim.effects import build_pipeline
    from vistac_sim.generate.chunks import commit_chunk, make_chunk
    from vistac_sim.generate.config import GenerateCfg
    from vistac_sim.generate.plan import plan_chunks
    from vistac_sim.generate.rigs import RigCache
    from vistac_sim.generate.run import object_specs
    from vistac_sim.objects.decomposition import default_cache_dir

    cfg = apply(GenerateCfg(n=chunk_size, seed=7), {"objects": {"n_objects": 1}})
    specs, _ = object_specs(cfg, cfg.seed)
    (chunk,) = plan_chunks(cfg.n, cfg.seed, len(specs), chunk_size)
    scenes = RigCache(specs, cfg, size=1, cache_dir=default_cache_dir())
    made = make_chunk(chunk, cfg, scenes, build_pipeline(cfg.effects))
    scenes.close()
    blob = pickle.dumps(made, protocol=5)
    shutil.rmtree(out, ignore_errors=True)
    (out / IMAGES).mkdir(parents=True)
    (out / PARTIAL / "shards").mkdir(parents=True)
    receive, commit = [], []
    for _ in range(repeats):
        t0 = time.process_time()
        back = pickle.loads(blob)
        t1 = time.process_time()
        commit_chunk(out, 0, back)
        receive.append(t1 - t0)
        commit.append(time.process_time() - t1)
    shutil.rmtree(out)
    return {"configurations": len(made), "bytes": len(blob),
            "receive_s": statistics.median(receive), "commit_s": statistics.median(commit)}


def cold_start(workers: int) -> float:
    """Seconds to start a local Ray instance, run one task and shut it down."""
    from vistac.engine import EngineCfg, ray_session

    t0 = time.perf_counter()
    with ray_session(EngineCfg(engine="ray"), num_cpus=workers) as ray:
        ray.get(ray.remote(_noop).remote(0))
    return time.perf_counter() - t0


# ----------------------------------------------------------------------------- the estimate
def driver_costs(med: dict, n: int) -> dict[str, float]:
    """Seconds per configuration the Ray driver spent in the generate runs beyond the local
    engine's parent process (CPU), and writing (wall)."""
    extra = med["ray"]["driver"] - med["local"]["driver"]
    return {"extra_cpu_s": extra / n, "commit_s": med["ray"]["commit"] / n}


def estimate(per_cfg: dict[str, float], machines: list[int], cores: int, gbit: float,
             local_cpu_s: float) -> list[dict]:
    """Configurations per second of a cluster, bounded by its workers, the driver and the
    network link the data crosses (the driver's, or the shared filesystem's); speed-up against
    one machine running the local engine at `local_cpu_s` per configuration."""
    rows = []
    for m in machines:
        bounds = {"workers": m * cores / per_cfg["worker_cpu_s"],
                  "driver": 1 / per_cfg["driver_s"],
                  "network": gbit * 1e9 / 8 / per_cfg["bytes"]}
        bound = min(bounds, key=bounds.get)
        rows.append({"machines": m, "cores": m * cores, **{f"{k}_cfg_s": v
                                                           for k, v in bounds.items()},
                     "cfg_s": bounds[bound], "bound": bound,
                     "speedup": bounds[bound] / (cores / local_cpu_s)})
    return rows


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--n", type=int, default=1000, help="configurations per generate run")
    p.add_argument("--workers", type=int, default=2, help="processes / Ray CPUs")
    p.add_argument("--repeats", type=int, default=3, help="interleaved local/Ray runs")
    p.add_argument("--noop-tasks", type=int, default=500, help="no-op tasks per measurement")
    p.add_argument("--cores-per-machine", type=int, default=16, help="for the estimate")
    p.add_argument("--gbit", type=float, default=1.0, help="network link (Gbit/s), estimate")
    p.add_argument("--out", type=Path, default=Path("runs/bench_ray"))
    p.add_argument("--results", type=Path, default=RESULTS)
    args = p.parse_args()
    from vistac.engine import EngineCfg, ray_session
    from vistac_sim.generate.config import GenerateCfg

    chunk_size = GenerateCfg().chunk_size
    full = driver_chunk_cost(chunk_size, 5, args.out / "driver")
    print(f"driver, one full chunk: receive {1e3 * full['receive_s']:.1f} ms, commit "
          f"{1e3 * full['commit_s']:.1f} ms CPU, {full['bytes'] / 1e3:.0f} kB")
    cold = cold_start(args.workers)
    print(f"cold start of a local Ray instance (start, one task, shut down): {cold:.1f} s")
    with ray_session(EngineCfg(engine="ray"), num_cpus=args.workers) as ray:
        noop = noop_overhead(ray, args.workers, args.noop_tasks)
        print("no-op tasks (ms per task): " + ", ".join(f"{k} {v:.2f}" for k, v in noop.items()))
        runs = generate_pairs(args.n, args.workers, args.repeats, args.out)
    shutil.rmtree(args.out, ignore_errors=True)

    med = {e: {k: statistics.median(r[k] for r in rs) for k in rs[0] if k != "commits"}
           for e, rs in runs.items()}
    chunks = med["ray"]["chunks"]
    cost = driver_costs(med, args.n)
    # the driver per full chunk: what it does with the chunk, plus a whole no-op task through
    # RayRunner (driver, worker and daemons: an upper bound of the driver's share)
    full["task_s"] = noop["runner_cpu_ms"] / 1e3
    full["total_s"] = full["receive_s"] + full["commit_s"] + full["task_s"]
    n_full = full["configurations"]
    # per configuration, for the estimate: making it (Ray workers, driver writing) and writing
    # it (the full chunk's commit) go to the workers or the driver
    make = (med["ray"]["workers"] + med["ray"]["daemons"]) / args.n
    write = full["commit_s"] / n_full
    modes = {"driver writes": {"driver_s": full["total_s"] / n_full, "worker_cpu_s": make,
                               "bytes": full["bytes"] / n_full},
             "workers write": {"driver_s": full["task_s"] / n_full, "worker_cpu_s": make + write,
                               "bytes": full["bytes"] / n_full}}
    machines = [1, 2, 4, 8]
    est = {mode: estimate(pc, machines, args.cores_per_machine, args.gbit, make + write)
           for mode, pc in modes.items()}

    rows = [("setup", "n", args.n, "configurations"), ("setup", "workers", args.workers, "CPUs"),
            ("setup", "repeats", args.repeats, "runs"),
            ("setup", "chunk_size", chunk_size, "configurations"),
            ("setup", "cpu_count", os.cpu_count(), "cores"),
            ("ray_task", "cold_start", round(cold, 2), "s")]
    rows += [("ray_task", k, round(v, 3), "ms/task") for k, v in noop.items()]
    for e, rs in runs.items():
        for i, r in enumerate(rs):
            rows += [(f"generate_{e}", f"repeat{i}_wall", round(r["wall"], 2), "s"),
                     (f"generate_{e}", f"repeat{i}_cpu", round(r["cpu"], 2), "s")]
        m = med[e]
        rows += [(f"generate_{e}", "median_wall", round(m["wall"], 2), "s"),
                 (f"generate_{e}", "median_cpu", round(m["cpu"], 2), "s"),
                 (f"generate_{e}", "median_driver_cpu", round(m["driver"], 2), "s"),
                 (f"generate_{e}", "median_worker_cpu", round(m["pool"] + m["workers"], 2), "s"),
                 (f"generate_{e}", "median_ray_daemon_cpu", round(m["daemons"], 2), "s"),
                 (f"generate_{e}", "cfg_per_s", round(args.n / m["wall"], 2), "cfg/s"),
                 (f"generate_{e}", "cpu_ms_per_cfg", round(1e3 * m["cpu"] / args.n, 2), "ms"),
                 (f"generate_{e}", "cpu_over_local", round(m["cpu"] / med["local"]["cpu"], 3),
                  "")]
    rows += [("driver_writes", "extra_cpu_per_cfg", round(cost["extra_cpu_s"], 5), "s"),
             ("driver_writes", "commit_wall_per_cfg", round(cost["commit_s"], 5), "s"),
             ("driver_writes", "configurations_per_chunk", round(args.n / chunks, 1), ""),
             ("full_chunk", "configurations", n_full, ""),
             ("full_chunk", "bytes", full["bytes"], "B"),
             ("full_chunk", "driver_receive_cpu", round(full["receive_s"], 4), "s"),
             ("full_chunk", "driver_commit_cpu", round(full["commit_s"], 4), "s"),
             ("full_chunk", "task_overhead_cpu", round(full["task_s"], 4), "s")]
    for mode, pc in modes.items():
        tag = mode.replace(" ", "_")
        rows += [(f"per_cfg_{tag}", k, round(v, 5), "B" if k == "bytes" else "s")
                 for k, v in pc.items()]
        for r in est[mode]:
            rows += [(f"estimate_{tag}_{r['machines']}m", k,
                      round(v, 1) if isinstance(v, float) else v,
                      "cfg/s" if k.endswith("cfg_s") else "") for k, v in r.items()
                     if k != "machines"]
    from ray_overhead_report import markdown, write_results

    md = markdown(args, cold, noop, runs, med, modes, cost, full, est, chunk_size, chunks)
    write_results(args.results, rows, md)
    print(md)


if __name__ == "__main__":
    sys.exit(main())
