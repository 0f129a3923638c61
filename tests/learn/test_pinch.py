"""The pinch view and model: frames that fit together, an exact and differentiable composition.

- A hand-built pinch (two fingertips, known contact points): the view's side numbers and the
  contact targets, composed by `compose_labels`, give exactly the closing axis in each finger's
  sensor frame (computed independently by the geometric baseline's `sensor_direction`), also
  in a mirrored, turned, shifted and scaled (jittered) view.
- The friction clamp puts a label outside the cone on its edge; the composition has gradients
  (gradcheck).
- The simulator's truth (`contact_truth`) lies where the image shows it, and is unknown for
  data without the columns.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch

from tests.learn_fixtures import make_dataset
from vistac.dataset import FINGERS, open_tables
from vistac.dataset.schema import PIXEL_CENTRE
from vistac.projection import Projection
from vistac_learn.data.contacts import contact_truth
from vistac_learn.data.fingertip_table import fingertip_table, simulator_tips
from vistac_learn.data.fingertips import Fingertip
from vistac_learn.data.pinch_view import PinchView, contact_targets, pinch_features
from vistac_learn.data.views import Aug, SampleInfo, TipCfg, mirror_labels
from vistac_learn.evaluate.geometric import sensor_direction
from vistac_learn.models.pinch import PinchModel, PinchNet, closing_axis, compose_labels


def _unit(v) -> np.ndarray:
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


# index on the left pointing right and a little down, thumb on the right pointing left and up
TIPS = {"index": Fingertip(np.array([60.0, 110.0]), _unit([1.0, 0.12]), 13.0),
        "thumb": Fingertip(np.array([170.0, 95.0]), _unit([-1.0, -0.2]), 12.0)}
CONTACTS = {"index": np.array([72.5, 113.0]), "thumb": np.array([158.0, 92.5])}


def _expected() -> dict[str, np.ndarray]:
    """Each finger's label: the other finger's contact -> its own, in its sensor frame."""
    return {f: sensor_direction(_unit(CONTACTS[f] - CONTACTS[g]), TIPS[f].axis, f)
            for f, g in (("index", "thumb"), ("thumb", "index"))}


def _compose(aug: Aug, normals: dict[str, np.ndarray], mu: float = 0.8) -> np.ndarray:
    """The composed labels (2, 2) of the hand-built pinch from the view's own numbers."""
    cfg = TipCfg()
    info = SampleInfo(tips=TIPS, contacts={
        f: (CONTACTS[f], normals[f], TIPS[f].axis) for f in FINGERS})
    view = PinchView(cfg)
    side = torch.from_numpy(view.side(info, aug, FINGERS))[None].double()
    aux = torch.from_numpy(view.aux(info, aug, FINGERS))[None].double()
    out = compose_labels(aux[..., 0:2], aux[..., 2:4], aux[..., 4], torch.zeros(1, 2,
                         dtype=torch.float64), side, mu)
    return out[0].numpy()


@pytest.mark.parametrize("aug", [Aug(), Aug(mirror=True), Aug(shift=(0.08, -0.05), turn=1.7,
                                                               scale=1.04),
                                 Aug(mirror=True, shift=(-0.1, 0.1), turn=-2.0, scale=0.95)])
def test_the_composition_is_exact_for_a_hand_built_pinch(aug):
    exp = _expected()
    got = _compose(aug, exp)  # normals along the axis: the friction clamp stays out of it
    for i, f in enumerate(FINGERS):
        want = mirror_labels(exp[f]) if aug.mirror else exp[f]
        np.testing.assert_allclose(got[i], want, atol=1e-9)
    assert exp["index"][1] < 0 and exp["thumb"][1] < 0  # both pushed against their approach


def test_a_label_outside_the_friction_cone_lands_on_its_edge():
    exp = _expected()
    tilt = np.radians(50.0)  # normal 50 deg off the closing axis; cone half-angle atan(0.8)
    c, s = np.cos(tilt), np.sin(tilt)
    normals = {f: np.array([c * v[0] - s * v[1], s * v[0] + c * v[1]]) for f, v in exp.items()}
    got = _compose(Aug(), normals, mu=0.8)
    for i, f in enumerate(FINGERS):
        angle = np.degrees(np.arccos(np.clip(got[i] @ normals[f], -1, 1)))
        assert angle == pytest.approx(np.degrees(np.arctan(0.8)), abs=1e-6)
        # on the side of the closing axis: closer to it than the normal is
        assert got[i] @ exp[f] > normals[f] @ exp[f]
    inside = _compose(Aug(), normals, mu=2.0)  # a wider cone holds the axis: no clamp
    for i, f in enumerate(FINGERS):
        np.testing.assert_allclose(inside[i], exp[f], atol=1e-9)


def test_the_composition_is_differentiable():
    rng = np.random.default_rng(0)
    side = torch.from_numpy(np.stack([pinch_features(TIPS, f, TipCfg(), Aug())
                                      for f in FINGERS]))[None].double().repeat(3, 1, 1)
    p = torch.tensor(rng.normal(0, 0.1, (3, 2, 2)), requires_grad=True)
    n = torch.tensor(np.tile([0.1, -1.0], (3, 2, 1)) + rng.normal(0, 0.05, (3, 2, 2)),
                     requires_grad=True)
    phi = torch.tensor(rng.normal(0, 0.02, (3, 2)), requires_grad=True)
    delta = torch.tensor(rng.normal(0, 0.02, (3, 2)), requires_grad=True)
    mu = torch.tensor(0.8, dtype=torch.float64, requires_grad=True)
    assert torch.autograd.gradcheck(
        lambda *a: compose_labels(a[0], a[1], a[2], a[3], side, a[4]), (p, n, phi, delta, mu))
    out = compose_labels(p, n, phi, delta, side, mu)
    out.sum().backward()
    assert p.grad.abs().sum() > 0 and phi.grad.abs().sum() > 0


def test_a_finger_not_found_gives_the_fallback():
    tips = dict(TIPS, thumb=Fingertip.missing("test"))
    side = torch.from_numpy(np.stack([pinch_features(tips, f, TipCfg(), Aug())
                                      for f in FINGERS]))[None]
    assert (side == 0).all()
    axis = closing_axis(torch.zeros(1, 2, 2), side)
    np.testing.assert_allclose(axis.numpy(), [[[0.0, -1.0], [0.0, -1.0]]])
    assert np.isnan(contact_targets(tips["thumb"], None, "thumb", TipCfg(), Aug())).all()


def test_the_model_outputs_the_fingers_it_is_asked_for():
    torch.manual_seed(0)
    x, side = torch.rand(3, 2, 3, 48, 48), torch.rand(3, 2, 8)
    both = PinchModel(PinchNet(out_features=64), FINGERS).eval()
    thumb = PinchModel(PinchNet(out_features=64), ("thumb",)).eval()
    thumb.load_state_dict(both.state_dict())
    with torch.no_grad():
        out, geo = both(x, side, aux=True)
        assert out.shape == (3, 4) and set(geo) == {"p", "normal", "phi"}
        np.testing.assert_allclose(thumb(x, side).numpy(), out[:, 2:].numpy(), atol=1e-6)
    nan = torch.full((3, 2, 5), float("nan"))
    assert float(PinchModel.aux_loss(geo, nan)) == 0.0  # no truth: no auxiliary loss


def test_contact_truth_lies_on_the_drawn_pads(tmp_path):
    data = make_dataset(tmp_path / "ds", n=12)
    t = open_tables(data)
    truth = contact_truth(t)
    assert truth.known.all()
    tips = fingertip_table(t, cache_dir=tmp_path / "cache")
    for row in range(len(t.configs)):
        for i, f in enumerate(FINGERS):
            tip = tips.get(row, f)
            # the contact is one fingertip radius from the tip centre
            gap = np.linalg.norm(truth.point[row, i] - tip.tip)
            assert gap == pytest.approx(tip.radius, rel=0.15, abs=1.0)
            assert truth.axis[row, i] @ tip.axis > np.cos(np.radians(3))
    configs = t.configs.drop(columns=[c for c in t.configs if c.startswith("target_")])
    configs.to_parquet(data / "configs.parquet")
    assert not contact_truth(open_tables(data)).known.any()
    # a rolled camera turns the image about its centre: the contact and the axis turn with it
    moved = t.configs.assign(camera_roll_deg=np.where(np.arange(len(t.configs)) == 0, 2.0, 0.0))
    moved.to_parquet(data / "configs.parquet")
    rolled = contact_truth(open_tables(data))
    assert rolled.known.all()
    np.testing.assert_array_equal(rolled.point[1:], truth.point[1:])
    centre = 96 / 2 - PIXEL_CENTRE
    for i in range(len(FINGERS)):
        a, b = truth.point[0, i] - centre, rolled.point[0, i] - centre
        assert np.linalg.norm(b) == pytest.approx(np.linalg.norm(a), rel=1e-9)
        turn = np.degrees(np.arctan2(a[0] * b[1] - a[1] * b[0], a @ b))
        c, d = truth.axis[0, i], rolled.axis[0, i]
        assert abs(turn) == pytest.approx(2.0, abs=1e-6)
        assert np.degrees(np.arctan2(c[0] * d[1] - c[1] * d[0], c @ d)) == pytest.approx(turn)


def test_clean_contact_truth_is_the_plain_top_view_bit_for_bit(tmp_path):
    """The one projection (`vistac.projection`) gives a plain top view's targets exactly as the
    formula the learner used before it: u = (x - camera_x) s + W/2 - 0.5, v = -(y - camera_y)
    s + H/2 - 0.5, the axis (x, -y) normalised."""
    t = open_tables(make_dataset(tmp_path / "ds", n=12))
    truth, c = contact_truth(t), t.configs
    s, cx, cy = (c[k].to_numpy(float) for k in ("px_per_m", "camera_x", "camera_y"))
    for i, f in enumerate(FINGERS):
        x, y = c[f"target_{f}_x"].to_numpy(float), c[f"target_{f}_y"].to_numpy(float)
        point = np.stack([(x - cx) * s + 96 / 2, -(y - cy) * s + 96 / 2], 1) - PIXEL_CENTRE
        ax = c[[f"approach_{f}_x", f"approach_{f}_y"]].to_numpy(float) * np.array([1.0, -1.0])
        assert np.array_equal(truth.point[:, i], point)
        assert np.array_equal(truth.axis[:, i], ax / np.linalg.norm(ax, axis=1, keepdims=True))


def test_photo_contact_truth_lies_on_the_pads(tmp_path):
    """`--preset photo` (a tilted, rolled perspective camera, fingers drawn by hand): every
    contact point and finger axis is known (before, these configurations had no truth), one
    fingertip radius from the simulator's fingertip in the image (`simulator_tips`, projected
    from the tip columns) and along its axis."""
    from vistac.cli import main

    out = tmp_path / "photo"
    assert main(["generate", "--n", "6", "--preset", "photo", "--seed", "5", "--workers", "1",
                 "--no-progress", "--out", str(out)]) == 0
    t = open_tables(out)
    assert (t.configs["camera_fovy_deg"] > 0).all() and (t.configs["camera_tilt_deg"] > 0).all()
    truth = contact_truth(t)
    assert truth.known.all()
    for row in range(len(t.configs)):
        c = t.configs.iloc[row]
        proj = Projection.from_columns(c, 227)
        for i, (f, (tip, axis)) in enumerate(simulator_tips(t, row, 227).items()):
            at = [c[f"target_{f}_x"], c[f"target_{f}_y"], t.hand["height"]]
            radius = t.hand["tip_radius"] * proj.px_per_m_at(np.array(at))  # the local scale
            gap = np.linalg.norm(truth.point[row, i] - tip)
            assert gap == pytest.approx(radius, rel=0.03), (row, f)
            assert truth.axis[row, i] @ axis > np.cos(np.radians(1)), (row, f)
