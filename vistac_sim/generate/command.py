"""`vistac generate`: its options (declared by the config tree's fields) and handler."""

from __future__ import annotations

import argparse
import json
from dataclasses import dataclass

from vistac.config import Config, apply, param
from vistac.config_options import (
    HelpFormatter,
    add_options,
    flag_labels,
    from_options,
    option_values,
)
from vistac.engine import ENGINE_OPTIONS, WRITES_OPTIONS, EngineCfg
from vistac.progress import add_progress_option, progress_wanted
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
COMMAND_OPTIONS = ("out", "preset", "scene", "recordings", "workers", "resume")
# Options a scene file may set too (field -> argparse dest): given, they win; not given, the
# scene file's value (else the field's default) stays.
SCENE_FILE_OPTIONS = {"physics.friction": "friction",
                      "grasp.approach_spread_deg": "approach_spread"}


@dataclass(frozen=True)
class GenerateCommandCfg(Config):
    """The options of `vistac generate` besides the dataset's config (`GenerateCfg`) and the
    engine's (`EngineCfg`): where, which preset and scene file, how many processes."""

    out: str = param(help="dataset folder to create")
    preset: str | None = param(None, choices=tuple(PRESETS), help="named set of effects: clean "
                               "(nothing but --noise), lab (what the reference study's set-up "
                               "suffered), harsh (more), photo (appearance only: textures, "
                               "light, phone camera, hand-drawn fingers; labels as clean); "
                               "default: the scene file's preset, else clean")
    scene: str | None = param(None, metavar="FILE", help="YAML or TOML file switching effects "
                              "on/off with parameters, merged over the preset")
    recordings: bool = param(False, help="also write recordings/NNNNNN.csv per configuration "
                             "in the RH8D/FTS-3 layout (50 Hz press/hold/release session, "
                             "integer mN)")
    workers: int = param(0, ge=0, help="processes (0: all cores; at most the cores and the "
                         "chunks); with --engine ray and no cluster: the CPUs of the local Ray "
                         "instance")
    resume: bool = param(False, help="continue an interrupted run in --out")


def add_command(sub: argparse._SubParsersAction) -> None:
    """Register `vistac generate`."""
    p = sub.add_parser(
        "generate",
        help="simulate presses and write a visuo-tactile dataset",
        description="Press a two-finger hand against objects in MuJoCo; write top-view images, "
        "fingertip force labels and a manifest into a dataset folder.",
        formatter_class=HelpFormatter,
    )
    add_options(p, GenerateCommandCfg, ("out",))
    add_options(p, GenerateCfg, RUN_OPTIONS)
    # --noise is the noise effect's field; unset, the scene file's value (else 0) stays
    (noise,) = add_options(p, GenerateCfg, ("effects.noise",), unset=True)
    noise.default_text = "the scene file's effects.noise, else 0"
    add_options(p, GenerateCommandCfg, ("preset", "scene", "recordings"))
    add_options(p, GenerateCfg, DRAW_OPTIONS)
    add_options(p, GenerateCommandCfg, ("workers",))
    add_options(p, EngineCfg, ENGINE_OPTIONS + WRITES_OPTIONS)
    for action in add_options(p, GenerateCfg, SCENE_OPTIONS):
        if action.dest in SCENE_FILE_OPTIONS.values():  # None unless given: the scene's stays
            action.default = None
    add_options(p, GenerateCommandCfg, ("resume",))
    add_progress_option(p)
    p.set_defaults(func=_generate)


def generate_cfg_from_args(args: argparse.Namespace) -> GenerateCfg:
    """The checked config tree for the options of `vistac generate`.

    Raises:
        UserError: an option, preset or scene file value its field does not allow.
    """
    cmd = from_options(GenerateCommandCfg, args, COMMAND_OPTIONS)
    base = GenerateCfg.from_preset(cmd.preset, scene=cmd.scene, noise=args.noise,
                                   recordings=cmd.recordings)
    values = option_values(args, GenerateCfg, OPTIONS)
    for path in SCENE_FILE_OPTIONS:
        section, name = path.split(".")
        if values[section][name] is None:  # not given
            del values[section][name]
    cfg = apply(base, values, labels=flag_labels(GenerateCfg, OPTIONS))
    return cfg


def _generate(args: argparse.Namespace) -> int:
    from vistac.api import generate
    from vistac_sim.generate.objects_report import format_summary

    cfg = generate_cfg_from_args(args)
    cmd = from_options(GenerateCommandCfg, args, COMMAND_OPTIONS)
    engine = from_options(EngineCfg, args, ENGINE_OPTIONS + WRITES_OPTIONS)
    dataset = generate(cfg, cmd.out, workers=cmd.workers, resume=cmd.resume,
                       progress=progress_wanted(args), engine=engine)
    manifest = dataset.manifest
    if dataset.already_complete:
        print(f"nothing to do: {cmd.out} holds the complete dataset "
              f"({manifest['counts']['configs']} configurations), checked")
        return 0
    summary = {k: manifest[k] for k in ("counts", "redraws", "wall_time_s")}
    print(format_summary(manifest["per_object"]))
    print(f"wrote {cmd.out}: " + json.dumps(summary))
    return 0
