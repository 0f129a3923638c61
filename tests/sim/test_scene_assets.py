"""The hand's MJCF asset: it compiles alone, and every scene variant built from it loads, presses
and settles without a single MuJoCo warning (Menagerie's model test, for our scenes)."""

from __future__ import annotations

import numpy as np
import pytest

from vistac.config import apply
from vistac_sim.assets import EXAMPLE_MESHES, HAND_XML, SCENE_XML
from vistac_sim.generate.config import GenerateCfg
from vistac_sim.generate.rigs import ObjectRig
from vistac_sim.mj import mujoco
from vistac_sim.objects.library import build_object, mesh_library, procedural_library
from vistac_sim.objects.outlines import PROCEDURAL_FAMILIES
from vistac_sim.physics.checks import RejectedSample


def _step_clean(model: mujoco.MjModel, data: mujoco.MjData, steps: int) -> None:
    mujoco.mj_step(model, data, nstep=steps)
    assert not data.warning.number.any(), [mujoco.mjtWarning(i).name for i, w in
                                           enumerate(data.warning) if w.number]
    assert np.isfinite(data.qpos).all() and np.isfinite(data.qvel).all()


@pytest.mark.parametrize("path", [HAND_XML, SCENE_XML])
def test_asset_files_compile_and_step(path):
    model = mujoco.MjModel.from_xml_path(str(path))
    _step_clean(model, mujoco.MjData(model), 100)


def _variants() -> list[tuple[str, float]]:
    return [(family, friction) for family in PROCEDURAL_FAMILIES for friction in (0.0, 0.6)]


def _press_clean(scene: ObjectRig, cfg: GenerateCfg, presses: int = 2) -> None:
    """Pose drawn grasps, drive both fingers and settle: never a warning."""
    rng, done = np.random.default_rng(0), 0
    for _ in range(50):
        try:
            grasp = scene.sampler.sample(rng)
        except RejectedSample:  # the fingers do not fit beside the object there
            continue
        scene.press.pose(grasp)  # both phases of a press: approach, release, settle
        _step_clean(scene.model, scene.press.data, cfg.physics.approach_steps)
        scene.press.release()
        _step_clean(scene.model, scene.press.data, cfg.physics.settle_steps)
        done += 1
        if done == presses:
            return
    pytest.fail("no grasp could be drawn")


@pytest.mark.parametrize("family, friction", _variants())
def test_every_procedural_scene_presses_without_warnings(family, friction):
    cfg = apply(GenerateCfg(), {"physics": {"friction": friction}})
    spec = next(s for s in procedural_library(cfg.objects, 0) if s.family == family)
    scene = ObjectRig(build_object(spec, cfg.hand.height), cfg, render=False)
    assert scene.model.geom_condim[scene.ids.pad["index"]] == (1 if friction == 0 else 3)
    _press_clean(scene, cfg)


def test_user_mesh_scenes_press_without_warnings(tmp_path):
    cfg = GenerateCfg()
    cfg = apply(cfg, {"objects": {"paths": (str(EXAMPLE_MESHES),)}})
    specs, skipped = mesh_library(cfg.objects, 0, cfg.hand.height, tmp_path)
    assert len(specs) == 2 and not skipped
    for friction in (0.0, 0.6):
        cfg = apply(cfg, {"physics": {"friction": friction}})
        for spec in specs:
            obj = build_object(spec, cfg.hand.height, cache_dir=tmp_path)
            _press_clean(ObjectRig(obj, cfg, render=False), cfg)


def test_config_edits_reach_the_model():
    cfg = GenerateCfg()
    cfg = apply(cfg, {"hand": {"tip_radius": 0.011}, "physics": {"timestep": 0.001},
                      "render": {"image_size": 64}})
    spec = procedural_library(cfg.objects, 0)[0]
    scene = ObjectRig(build_object(spec, cfg.hand.height), cfg, render=False)
    m = scene.model
    assert m.geom_size[scene.ids.pad["thumb"], 0] == 0.011
    assert m.opt.timestep == 0.001 and m.vis.global_.offwidth == 64
    np.testing.assert_allclose(m.site_pos[scene.ids.site["index"]], [0.011, 0.0, 0.0])
