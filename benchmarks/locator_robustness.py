"""The fingertip locator on clean, perturbed and photo-preset images, against the simulator's truth.

For each image of a generated dataset and each perturbation (`vistac_learn.data.perturb`: one
axis at a time and all at once, drawn from (seed, row, perturbation)), and for the images of a
``--preset photo`` dataset (case ``photo``; its truth projected by its perspective camera), the
colour fit, the learned fit and the colour fit inside the learned fingers
(`vistac_learn.data.fingertips`) run once on the image, and five locators made from them are
compared side by side (`MODES`: colour alone, learned alone, and the `LocatorCfg.segmenter`
combinations ``fallback``, ``check`` and ``refine``). Their tip centre and finger
axis are compared with the simulator's (the ``tip_*`` / ``approach_*`` columns of
``configs.parquet``, moved by the perturbation's homography). Reported per case, locator and
finger: found %, % within the agreed tolerance (found, tip < 2 px, axis < 3 deg); per case and
locator: tip error (median, 99th percentile, max, px), axis error (same, deg), CPU ms per
image, and the failure reasons.

Writes ``locator_robustness.md`` / ``.json`` into ``--out``.

Usage:
    python benchmarks/locator_robustness.py --out benchmarks/results --n 200
    (the datasets: `vistac generate --n 1000 --noise 0.05 --seed 21 --split-by object` and the
    same with `--n 300 --preset photo`, made under <out>/data unless --data / --photo are given)
"""

from __future__ import annotations

import argparse
import collections
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from learnbench import ensure_dataset, headline_data, save

from vistac.dataset import FINGERS, open_tables
from vistac.dataset.splits import SplitCfg
from vistac_learn.data.fingertip_table import simulator_tips
from vistac_learn.data.fingertips import LOCATOR_VERSION, LocatorCfg, colour_fingertips
from vistac_learn.data.locator import combine, learned_fit, locate_fingertips, refined_fingertips
from vistac_learn.data.perturb import (
    PERTURBATIONS,
    Scene,
    map_direction,
    map_points,
    perturb,
    segment,
)
from vistac_learn.data.variants import read_rgb
from vistac_sim.generate.config import GenerateCfg

TIP_PX, AXIS_DEG = 2.0, 3.0  # the agreed tolerance (tests/learn/test_fingertips.py)


MODES = ("colour", "learned", "fallback", "check", "refine")
"""The locators compared: the colour fit alone (segmenter off), the learned segmenter's labels
alone (always), and the combinations of `LocatorCfg.segmenter` (fallback, check, refine)."""


def _errors(found, truth, hom) -> dict[str, tuple[float, float]]:
    """Per finger (tip px, axis deg) against the truth moved by `hom`; NaN when not found."""
    out = {}
    for f in FINGERS:
        tip, axis = truth[f]
        got = found[f]
        if not got.ok:
            out[f] = (np.nan, np.nan)
            continue
        tip_p = map_points(hom, tip[None])[0]
        axis_p = map_direction(hom, tip, axis)
        out[f] = (float(np.hypot(*(got.tip - tip_p))),
                  float(np.degrees(np.arccos(np.clip(got.axis @ axis_p, -1.0, 1.0)))))
    return out


def _cases(data: Path, photo: Path | None, n: int, seed: int, names: tuple[str, ...]):
    """(case name, image, truth, homography, finger colours) of every measured image: the
    clean dataset's images clean and perturbed, then the photo dataset's images."""
    t = open_tables(data)
    colours = {f: t.finger_rgb(f) for f in FINGERS}
    rows = np.random.default_rng(seed).permutation(len(t.configs))[:n]
    for row in rows:
        rgb = read_rgb(t.image_path(int(row)))
        truth = simulator_tips(t, int(row), rgb.shape[0])
        scene = Scene(segment(rgb, colours, t.table_rgb), colours)
        for k, name in enumerate(names):
            if name == "clean":
                yield name, rgb, truth, np.eye(3), colours
                continue
            p = perturb(name, rgb, scene, np.random.default_rng([seed, int(row), k]))
            yield name, p.rgb, truth, p.homography, colours
    if photo is None:
        return
    t = open_tables(photo)
    colours = {f: t.finger_rgb(f) for f in FINGERS}
    for row in np.random.default_rng(seed).permutation(len(t.configs))[:n]:
        rgb = read_rgb(t.image_path(int(row)))
        yield "photo", rgb, simulator_tips(t, int(row), rgb.shape[0]), np.eye(3), colours


def measure(data: Path, photo: Path | None, n: int, seed: int, names: tuple[str, ...],
            cfg: LocatorCfg) -> dict:
    """Per case (perturbation or photo), locator (`MODES`) and finger: errors, found counts,
    reasons and time. The colour and the learned fits run once per image; the combinations
    are made from them (`combine`) and charged the time of what they run."""
    rec = {}
    for name, img, truth, hom, colours in _cases(data, photo, n, seed, names):
        t0 = time.process_time()
        colour = colour_fingertips(img, colours, cfg)
        t1 = time.process_time()
        learned, masks = learned_fit(img, colours, cfg)
        t2 = time.process_time()
        refined = refined_fingertips(img, colours, cfg, masks)
        t3 = time.process_time()
        tc, tl, tr = t1 - t0, t2 - t1, t3 - t2
        results = {
            "colour": (colour, tc), "learned": (learned, tl),
            "fallback": (combine(colour, learned, replace(cfg, segmenter="fallback")),
                         tc + (0.0 if all(v.ok for v in colour.values()) else tl)),
            "check": (combine(colour, learned, replace(cfg, segmenter="check")), tc + tl),
            "refine": (combine(None, learned, replace(cfg, segmenter="refine"), refined),
                       tl + tr)}
        for mode, (found, secs) in results.items():
            r = rec.setdefault(name, {}).setdefault(mode, {
                "tip": {f: [] for f in FINGERS}, "axis": {f: [] for f in FINGERS},
                "reasons": collections.Counter(), "seconds": 0.0, "images": 0})
            r["seconds"] += secs
            r["images"] += 1
            for f, (tip_e, axis_e) in _errors(found, truth, hom).items():
                r["tip"][f].append(tip_e)
                r["axis"][f].append(axis_e)
                if not found[f].ok:
                    r["reasons"][f"{f}: {found[f].reason}"] += 1
    out = {}
    for name, modes in rec.items():
        out[name] = {}
        for mode, r in modes.items():
            per = {}
            for f in [*FINGERS, "both"]:
                if f == "both":
                    tip = np.concatenate([r["tip"][g] for g in FINGERS])
                    ax = np.concatenate([r["axis"][g] for g in FINGERS])
                else:
                    tip, ax = np.array(r["tip"][f]), np.array(r["axis"][f])
                per[f] = _stats(tip, ax)
            out[name][mode] = {"fingers": per, "ms_per_image": 1000 * r["seconds"] / r["images"],
                               "images": r["images"],
                               "reasons": dict(r["reasons"].most_common(8))}
    return {"n_images": int(n), "results": out}


def _stats(tip: np.ndarray, ax: np.ndarray) -> dict:
    """Found %, within-tolerance % and error percentiles of one finger's (or both's) errors."""
    ok = np.isfinite(tip)
    good = ok & (np.nan_to_num(tip, nan=1e9) < TIP_PX) & (np.nan_to_num(ax, nan=1e9) < AXIS_DEG)
    stats = {"found_pct": 100.0 * ok.mean(), "within_tol_pct": 100.0 * good.mean()}
    for key, v in (("tip", tip), ("axis", ax)):
        unit = "px" if key == "tip" else "deg"
        for s, fn in (("median", np.median), ("max", np.max),
                      ("p99", lambda x: np.percentile(x, 99))):
            stats[f"{key}_{s}_{unit}"] = float(fn(v[ok])) if ok.any() else None
    return stats


def speed(data: Path, n: int, rev: str) -> dict:
    """Milliseconds per clean image of this locator and of the one at git revision `rev`,
    timed interleaved (image by image) so that a shared machine's load hits both alike."""
    import importlib.util
    import subprocess
    import tempfile

    src = subprocess.run(["git", "show", f"{rev}:vistac_learn/data/fingertips.py"],
                         capture_output=True, text=True, check=True,
                         cwd=Path(__file__).resolve().parent).stdout
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "fingertips_before.py"
        path.write_text(src)
        spec = importlib.util.spec_from_file_location("fingertips_before", path)
        before = importlib.util.module_from_spec(spec)
        sys.modules[spec.name] = before  # dataclasses look their module up
        spec.loader.exec_module(before)
    t = open_tables(data)
    colours = {f: t.finger_rgb(f) for f in FINGERS}
    imgs = [read_rgb(t.image_path(r)) for r in range(min(n, len(t.configs)))]
    secs = {"before": 0.0, "now": 0.0}
    for _ in range(2):
        for img in imgs:
            for key, fn in (("before", before.locate_fingertips), ("now", locate_fingertips)):
                t0 = time.perf_counter()
                fn(img, colours)
                secs[key] += time.perf_counter() - t0
    return {"rev": rev, "n_images": len(imgs),
            **{f"{k}_ms_per_image": 1000 * v / (2 * len(imgs)) for k, v in secs.items()}}


def grid(data: Path, n: int, seed: int, path: Path) -> None:
    """A JPEG of `n` images: clean, then each perturbation (as the benchmark draws them)."""
    import cv2

    t = open_tables(data)
    colours = {f: t.finger_rgb(f) for f in FINGERS}
    rows = np.random.default_rng(seed).permutation(len(t.configs))[:n]
    lines = []
    for row in rows:
        rgb = read_rgb(t.image_path(int(row)))
        scene = Scene(segment(rgb, colours, t.table_rgb), colours)
        tiles = [rgb] + [perturb(name, rgb, scene, np.random.default_rng([seed, int(row), k])).rgb
                         for k, name in enumerate(("clean", *PERTURBATIONS)) if k > 0]
        lines.append(np.concatenate(tiles, axis=1))
    img = np.concatenate(lines, axis=0)
    head = np.full((22, img.shape[1], 3), 255, np.uint8)
    w = rgb.shape[1]
    for k, name in enumerate(("clean", *PERTURBATIONS)):
        cv2.putText(head, name, (k * w + 6, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 0, 0), 1,
                    cv2.LINE_AA)
    cv2.imwrite(str(path), np.concatenate([head, img], axis=0)[..., ::-1],
                [cv2.IMWRITE_JPEG_QUALITY, 90])


def markdown(res: dict) -> str:
    """Two tables: found and within-tolerance % of every locator side by side (per case and
    finger), then errors and time per case and locator (both fingers pooled)."""
    f3 = lambda v: "-" if v is None else f"{v:.3g}"  # noqa: E731
    head = ["case", "finger", *(f"{m} found / within %" for m in MODES)]
    lines = ["| " + " | ".join(head) + " |", "|---" * len(head) + "|"]
    for name, modes in res["results"].items():
        for f in FINGERS:
            cells = [f"{modes[m]['fingers'][f]['found_pct']:.1f} / "
                     f"{modes[m]['fingers'][f]['within_tol_pct']:.1f}" for m in MODES]
            lines.append("| " + " | ".join([name, f, *cells]) + " |")
    head = ["case", "locator", "found %", "within %", "tip median px", "tip p99 px", "tip max px",
            "axis median deg", "axis p99 deg", "axis max deg", "CPU ms / image"]
    lines += ["", "Both fingers pooled:", "", "| " + " | ".join(head) + " |",
              "|---" * len(head) + "|"]
    for name, modes in res["results"].items():
        for m in MODES:
            s = modes[m]["fingers"]["both"]
            lines.append("| " + " | ".join([
                name, m, f"{s['found_pct']:.1f}", f"{s['within_tol_pct']:.1f}",
                f3(s["tip_median_px"]), f3(s["tip_p99_px"]), f3(s["tip_max_px"]),
                f3(s["axis_median_deg"]), f3(s["axis_p99_deg"]), f3(s["axis_max_deg"]),
                f"{modes[m]['ms_per_image']:.1f}"]) + " |")
    reasons = [f"- {name}, {m}: " + "; ".join(f"{k} ({v})" for k, v in r["reasons"].items())
               for name, modes in res["results"].items() for m, r in modes.items()
               if r["reasons"] and m in ("colour", LocatorCfg().segmenter)]
    return "\n".join(lines + ([""] + [f"Failure reasons (count), colour and "
                                       f"{LocatorCfg().segmenter}:"] + reasons
                              if reasons else []))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", type=Path, default=Path("benchmarks/results"))
    ap.add_argument("--data", type=Path, default=None, help="dataset (default: made in --out)")
    ap.add_argument("--n", type=int, default=300, help="images (a seeded sample)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--photo", type=Path, default=None, help="a --preset photo dataset of "
                    "other objects (default: made in --out; 'none' to skip)")
    ap.add_argument("--name", default="locator_robustness", help="results file name")
    ap.add_argument("--speed-rev", default="", help="git revision whose locator is "
                    "timed beside this one on clean images ('' to skip)")
    ap.add_argument("--grid", type=int, default=4, help="images in <out>/perturbations.jpg")
    ap.add_argument("--grid-only", action="store_true", help="write the grid, measure nothing")
    a = ap.parse_args()
    data = a.data or ensure_dataset(a.out / "data" / "d1000", headline_data(1000, 21))
    photo = None if str(a.photo) == "none" else a.photo or ensure_dataset(
        a.out / "data" / "photo300", GenerateCfg.from_preset(
            "photo", noise=0.05, n=300, seed=21, split=SplitCfg(by="object")))
    a.out.mkdir(parents=True, exist_ok=True)
    if a.grid:
        grid(data, a.grid, a.seed, a.out / "perturbations.jpg")
    if a.grid_only:
        return
    names = ("clean", *PERTURBATIONS)
    t0 = time.perf_counter()
    fast = speed(data, 100, a.speed_rev) if a.speed_rev else None
    res = measure(data, photo, a.n, a.seed, names, LocatorCfg())
    if fast:
        res["speed"] = fast
    res |= {"locator_version": LOCATOR_VERSION, "data": str(data), "photo": str(photo),
            "seed": a.seed,
            "wall_s": time.perf_counter() - t0,
            "tolerance": {"tip_px": TIP_PX, "axis_deg": AXIS_DEG}}
    md = (f"Fingertip locator v{LOCATOR_VERSION} on {res['n_images']} images of {data} "
          f"(x2 fingers), clean and perturbed (seed {a.seed}), and {res['n_images']} images of "
          f"the photo-preset dataset {photo}; segmenter weights trained on other seeds and "
          "objects (benchmarks/train_segmenter.py). Tolerance: found, tip < 2 px, axis < 3 "
          "deg. Shared 2-core machine: times are CPU time of this process, indicative.\n\n"
          + markdown(res))
    if "speed" in res:
        sp = res["speed"]
        md += (f"\n\nSpeed on {sp['n_images']} clean images, timed interleaved: "
               f"{sp['now_ms_per_image']:.1f} ms per image now, "
               f"{sp['before_ms_per_image']:.1f} ms with the locator of {sp['rev']}.")
    save(a.out, a.name, res, md, datasets=(data, photo))


if __name__ == "__main__":
    main()
