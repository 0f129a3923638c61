"""PNG encodings of `vistac_sim.render.png.encode_png` on clean and photo frames: CPU time and size.

Renders `--n` configurations of each preset (the images `generate` would write), then encodes
them all with each encoding in turn for `--rounds` rounds (interleaved, so load on a shared
machine hits both alike) and reports the median CPU ms per image and the mean KiB per image.
Every encoding is checked to decode to the same pixels (OpenCV).

    .venv/bin/python benchmarks/png_encoding.py --n 20 --rounds 7
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path

import cv2
import numpy as np

import vistac_sim.generate.configuration as configuration
from vistac.provenance import provenance
from vistac_sim.effects import build_pipeline
from vistac_sim.generate.config import GenerateCfg
from vistac_sim.generate.rigs import RigCache
from vistac_sim.generate.run import object_specs
from vistac_sim.render.png import encode_png

RESULTS = Path(__file__).parent / "results"
ENCODINGS = {"flat (no filter, zlib level 1)": False, "grainy (up filter, zlib RLE)": True}


def frames(preset: str, n: int, seed: int) -> list[np.ndarray]:
    """The RGB images of configurations 0..n-1 of `preset`, as `make_configuration` encodes
    them (caught at its `encode_png` call)."""
    cfg = GenerateCfg.from_preset(preset, n=n, seed=seed)
    specs, _ = object_specs(cfg, seed)
    scenes, pipeline = RigCache(specs, cfg, size=64), build_pipeline(cfg.effects)
    caught: list[np.ndarray] = []
    real = configuration.encode_png

    def catch(rgb: np.ndarray, *args, **kwargs) -> bytes:
        caught.append(rgb.copy())
        return real(rgb, *args, **kwargs)

    configuration.encode_png = catch
    try:
        for cid in range(n):
            configuration.make_configuration(cid, seed, scenes, cfg, pipeline)
    finally:
        configuration.encode_png = real
        scenes.close()
    return caught


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=20, help="configurations per preset")
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    res: dict = {"n": args.n, "rounds": args.rounds, "presets": {}}
    for preset in ("clean", "photo"):
        imgs = frames(preset, args.n, args.seed)
        ms: dict[str, list[float]] = {e: [] for e in ENCODINGS}
        kib: dict[str, float] = {}
        for _ in range(args.rounds):
            for name, grainy in ENCODINGS.items():
                c0 = time.process_time()
                blobs = [encode_png(im, grainy=grainy) for im in imgs]
                ms[name].append((time.process_time() - c0) / len(imgs) * 1e3)
                kib[name] = sum(map(len, blobs)) / len(blobs) / 1024
        for name, grainy in ENCODINGS.items():  # lossless: the same pixels back
            for im in imgs:
                back = cv2.imdecode(np.frombuffer(encode_png(im, grainy=grainy), np.uint8),
                                    cv2.IMREAD_UNCHANGED)
                assert np.array_equal(back[..., ::-1], im), (preset, name)
        res["presets"][preset] = {e: {"cpu_ms": statistics.median(ms[e]), "kib": kib[e]}
                                  for e in ENCODINGS}
    res["provenance"] = provenance()
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "png_encoding.json").write_text(json.dumps(res, indent=2) + "\n")
    lines = [f"# PNG encodings (227 px frames, {args.n} per preset, median of {args.rounds} "
             "rounds of CPU time; shared, noisy 2-core machine)", "",
             "| preset | encoding | CPU ms per image | KiB per image |", "|---|---|---|---|"]
    for preset, by in res["presets"].items():
        for name, v in by.items():
            lines.append(f"| {preset} | {name} | {v['cpu_ms']:.2f} | {v['kib']:.1f} |")
    lines += ["", "`generate` encodes frames with sensor noise or JPEG (the photo preset) as "
              "grainy, every other frame as flat."]
    text = "\n".join(lines) + "\n"
    (RESULTS / "png_encoding.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
