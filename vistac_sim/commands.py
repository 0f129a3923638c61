"""`vistac generate`: its options and the config tree they fill in."""

from __future__ import annotations

import argparse
import json

from vistac_sim.config import PROCEDURAL_FAMILIES, GenerateCfg
from vistac_sim.effects import build_pipeline
from vistac_sim.presets import PRESETS, resolve


def add_generate(sub: argparse._SubParsersAction) -> None:
    """Register `vistac generate`."""
    d = GenerateCfg()
    p = sub.add_parser(
        "generate",
        help="simulate presses and write a visuo-tactile dataset",
        description="Press a two-finger hand against objects in MuJoCo; write top-view images, "
        "fingertip force labels and a manifest into a dataset folder.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    p.add_argument("--out", required=True, help="dataset folder to create")
    p.add_argument("--n", type=int, default=d.n, help="number of grasp configurations")
    p.add_argument("--noise", type=float, default=None,
                   help="relative std of the per-press force measurement noise (default: the "
                   "scene file's effects.noise, else 0)")
    p.add_argument("--preset", choices=tuple(PRESETS), default=None,
                   help="named set of effects: clean (nothing but --noise), lab (what the "
                   "reference study's set-up suffered), harsh (more); default: the scene "
                   "file's preset, else clean")
    p.add_argument("--scene", metavar="FILE", default=None,
                   help="YAML or TOML file switching effects on/off with parameters, merged "
                   "over the preset")
    p.add_argument("--recordings", action="store_true",
                   help="also write recordings/NNNNNN.csv per configuration in the RH8D/FTS-3 "
                   "layout (50 Hz press/hold/release session, integer mN)")
    p.add_argument("--repeats", type=int, default=d.repeats, help="presses per configuration")
    p.add_argument("--seed", type=int, default=d.seed)
    p.add_argument("--workers", type=int, default=0, help="processes (0: all cores)")
    p.add_argument("--friction", type=float, default=d.physics.friction,
                   help="sliding friction coefficient (0: frictionless)")
    p.add_argument("--image-size", type=int, default=d.render.image_size)
    p.add_argument("--objects", nargs="+", default=[], metavar="PATH",
                   help="mesh files or folders (STL, OBJ, PLY, GLB) instead of the built-in "
                   "procedural families")
    p.add_argument("--families", nargs="+", default=list(d.objects.families),
                   choices=PROCEDURAL_FAMILIES, metavar="FAMILY",
                   help=f"procedural families ({', '.join(PROCEDURAL_FAMILIES)})")
    p.add_argument("--n-objects", type=int, default=d.objects.n_objects,
                   help="size of the procedural object library")
    p.add_argument("--footprint", type=float, nargs=2, default=list(d.objects.footprint),
                   metavar=("MIN", "MAX"), help="longest top-view side of objects, metres")
    p.add_argument("--approach-spread", type=float, default=d.grasp.approach_spread_deg,
                   help="max degrees of the approach direction off the surface normal")
    p.add_argument("--split-by", choices=("config", "object"), default=d.split.by)
    p.add_argument("--split", type=float, nargs=3, default=list(d.split.fractions),
                   metavar=("TRAIN", "VAL", "TEST"), help="split fractions")
    p.add_argument("--chunk-size", type=int, default=d.chunk_size,
                   help="configurations per shard (unit of work and of resume)")
    p.add_argument("--strict", action="store_true",
                   help="a bad mesh in a folder aborts the run instead of being skipped")
    p.add_argument("--resume", action="store_true", help="continue an interrupted run in --out")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=_generate)


def generate_cfg_from_args(args: argparse.Namespace) -> GenerateCfg:
    """The config tree for the options of `vistac generate`."""
    from vistac_sim.errors import UserError

    if args.n < 1 or args.repeats < 1:
        raise UserError("--n and --repeats must be at least 1")
    if (args.noise is not None and args.noise < 0) or args.friction < 0:
        raise UserError("--noise and --friction must not be negative")
    cfg = GenerateCfg(n=args.n, seed=args.seed, repeats=args.repeats, chunk_size=args.chunk_size)
    cfg.effects, cfg.recording = resolve(args.preset, args.scene, args.noise)
    cfg.recording.write = cfg.recording.write or args.recordings
    build_pipeline(cfg.effects)  # bad effect parameters fail here, before any work starts
    cfg.physics.friction = args.friction
    cfg.render.image_size = args.image_size
    cfg.objects.paths = tuple(args.objects)
    cfg.objects.families = tuple(args.families)
    cfg.objects.n_objects = args.n_objects
    cfg.objects.footprint = tuple(args.footprint)
    cfg.objects.strict = args.strict
    cfg.grasp.approach_spread_deg = args.approach_spread
    cfg.split.by = args.split_by
    cfg.split.fractions = tuple(args.split)
    return cfg


def _generate(args: argparse.Namespace) -> int:
    from vistac_sim.generate import generate

    cfg = generate_cfg_from_args(args)
    manifest = generate(cfg, args.out, workers=args.workers, resume=args.resume,
                        progress=not args.no_progress)
    summary = {k: manifest[k] for k in ("counts", "redraws", "wall_time_s")}
    print(f"wrote {args.out}: " + json.dumps(summary))
    return 0
