"""`vistac generate`: its options (declared by the config tree's fields) and handler."""

from __future__ import annotations

import argparse
import json

from vistac.config import (
    HelpFormatter,
    add_options,
    apply,
    flag_labels,
    from_options,
    option_values,
)
from vistac.engine import ENGINE_OPTIONS, WRITES_OPTIONS, EngineCfg
from vistac_sim.effects.presets import PRESETS
from vistac_sim.generate.config import GenerateCfg

# Config fields set by options, in the order `--help` lists them (between the others below).
RUN_OPTIONS = ("n",)
DRAW_OPTIONS = ("repeats", "seed")
SCENE_OPTIONS = ("physics.friction", "render.image_size", "render.masks", "render.textures",
                 "objects.paths", "objects.families",
                 "objects.n_objects", "objects.footprint", "grasp.approach_spread_deg", "split.by",
                 "split.fractions", "chunk_size", "objects.strict")
OPTIONS = RUN_OPTIONS + DRAW_OPTIONS + SCENE_OPTIONS


def add_command(sub: argparse._SubParsersAction) -> None:
    """Register `vistac generate`."""
    p = sub.add_parser(
        "generate",
        help="simulate presses and write a visuo-tactile dataset",
        description="Press a two-finger hand against objects in MuJoCo; write top-view images, "
        "fingertip force labels and a manifest into a dataset folder.",
        formatter_class=HelpFormatter,
    )
    p.add_argument("--out", required=True, help="dataset folder to create")
    add_options(p, GenerateCfg, RUN_OPTIONS)
    p.add_argument("--noise", type=float, default=None,
                   help="relative std of the per-press force measurement noise (default: the "
                   "scene file's effects.noise, else 0)")
    p.add_argument("--preset", choices=tuple(PRESETS), default=None,
                   help="named set of effects: clean (nothing but --noise), lab (what the "
                   "reference study's set-up suffered), harsh (more), photo (appearance only: "
                   "textures, light, phone camera, hand-drawn fingers; labels as clean); "
                   "default: the scene file's preset, else clean")
    p.add_argument("--scene", metavar="FILE", default=None,
                   help="YAML or TOML file switching effects on/off with parameters, merged "
                   "over the preset")
    p.add_argument("--recordings", action="store_true",
                   help="also write recordings/NNNNNN.csv per configuration in the RH8D/FTS-3 "
                   "layout (50 Hz press/hold/release session, integer mN)")
    add_options(p, GenerateCfg, DRAW_OPTIONS)
    p.add_argument("--workers", type=int, default=0,
                   help="processes (0: all cores; at most the cores and the chunks); with "
                   "--engine ray and no cluster: the CPUs of the local Ray instance")
    add_options(p, EngineCfg, ENGINE_OPTIONS + WRITES_OPTIONS)
    add_options(p, GenerateCfg, SCENE_OPTIONS)
    p.add_argument("--resume", action="store_true", help="continue an interrupted run in --out")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=_generate)


def generate_cfg_from_args(args: argparse.Namespace) -> GenerateCfg:
    """The checked config tree for the options of `vistac generate`.

    Raises:
        UserError: an option, preset or scene file value its field does not allow.
    """
    base = GenerateCfg.from_preset(args.preset, scene=args.scene, noise=args.noise,
                                   recordings=args.recordings)
    cfg = apply(base, option_values(args, GenerateCfg, OPTIONS),
                labels=flag_labels(GenerateCfg, OPTIONS))
    return cfg


def _generate(args: argparse.Namespace) -> int:
    from vistac.api import generate
    from vistac_sim.generate.objects_report import format_summary

    cfg = generate_cfg_from_args(args)
    engine = from_options(EngineCfg, args, ENGINE_OPTIONS + WRITES_OPTIONS)
    dataset = generate(cfg, args.out, workers=args.workers, resume=args.resume,
                       progress=not args.no_progress, engine=engine)
    manifest = dataset.manifest
    if dataset.already_complete:
        print(f"nothing to do: {args.out} holds the complete dataset "
              f"({manifest['counts']['configs']} configurations), checked")
        return 0
    summary = {k: manifest[k] for k in ("counts", "redraws", "wall_time_s")}
    print(format_summary(manifest["per_object"]))
    print(f"wrote {args.out}: " + json.dumps(summary))
    return 0
