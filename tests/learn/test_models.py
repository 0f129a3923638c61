"""Tests of the model registry: thesis architectures, baselines, MAC counting, `vistac models`."""

from __future__ import annotations

import argparse

import pytest
import torch
from torch import nn

from vistac_learn import models
from vistac_learn.models import command, count_macs, create_model, list_models, model_info, registry

# docs/study.md section 7, copied here independently of models.py: name -> (input, f, w).
THESIS_TABLE = {
    "AlexNet": (227, 9216, 4096),
    "AlexNet-1x1": (227, 256, 160),
    "RandomConv": (227, 320, 160),
    "SmallConv": (227, 360, 160),
    "SchoeConv100-V1": (100, 240, 160),
    "SchoeConv100-V2": (100, 240, 160),
    "SchoeConv100-V3(FC160)": (100, 240, 160),
    "SchoeConv100-V3(FC160)-4x4": (100, 3840, 160),
    "SchoeConv100-V3(FC480)": (100, 240, 480),
    "SchoeConv100-V4": (100, 240, 160),
    "SchoeConv100-V5": (100, 400, 160),
    "SchoeConv227-V1": (227, 240, 160),
    "SchoeConv227-V2": (227, 400, 160),
}

# Forward cost per image stated by docs/study.md (multiply-accumulates).
THESIS_MACS = {
    "AlexNet": 1.0e9,
    "SchoeConv100-V3(FC160)": 0.66e9,
    "SchoeConv100-V5": 1.8e9,
    "SchoeConv227-V1": 11.5e9,
    "SchoeConv227-V2": 31.7e9,
}
MACS_RTOL = 0.05  # the thesis figures carry two or three significant digits

# Models whose real forward pass costs more than ~5 G MACs per image: shape-checked on the meta
# device by default, run for real only with --runslow.
BIG = {"schoeconv227-v1", "schoeconv227-v2"}


def meta_model(name: str, in_channels: int = 1, out_features: int = 2) -> nn.Module:
    """Build a model on the meta device (shapes only, no memory, no arithmetic)."""
    with torch.device("meta"):
        return create_model(name, in_channels, out_features)


def test_registry_holds_every_thesis_model_and_two_baselines():
    names = list_models()
    assert len(names) == len(set(names))
    for display in THESIS_TABLE:
        assert registry._resolve(display).slug in names
    baselines = [n for n in names if registry._resolve(n).display not in THESIS_TABLE]
    assert len(baselines) >= 2
    assert names[: len(THESIS_TABLE)] == [registry._resolve(d).slug for d in THESIS_TABLE]


@pytest.mark.parametrize(
    ("alias", "slug"),
    [
        ("SchoeConv100-V3(FC160)", "schoeconv100-v3-fc160"),
        ("schoeconv100-v3(fc160)-4x4", "schoeconv100-v3-fc160-4x4"),
        ("SCHOECONV100-V3(FC480)", "schoeconv100-v3-fc480"),
        ("AlexNet-1x1", "alexnet-1x1"),
        ("alexnet", "alexnet"),
        (" SmallConv ", "smallconv"),
        ("SchoeConv227_V2", "schoeconv227-v2"),
    ],
)
def test_thesis_spelling_is_accepted_case_insensitively(alias, slug):
    assert meta_model(alias).name == slug
    assert model_info(alias)["name"] == slug


def test_unknown_name_lists_valid_names():
    with pytest.raises(ValueError, match="unknown model 'vgg16'.*schoeconv100-v3-fc160"):
        create_model("vgg16")


def test_register_model_rejects_duplicates_and_non_slugs():
    with pytest.raises(ValueError, match="already registered"):
        models.register_model("alexnet")
    with pytest.raises(ValueError, match="slug"):
        models.register_model("My Net")


@pytest.mark.parametrize("display", list(THESIS_TABLE))
def test_conv_stack_reaches_the_tables_fc_input(display):
    input_size, f, w = THESIS_TABLE[display]
    model = meta_model(display)
    assert model.input_size == input_size
    assert (model.fc_in, model.fc_width) == (f, w)
    maps = model.features(torch.zeros(1, 1, input_size, input_size, device="meta"))
    assert maps[0].numel() == f
    linears = [m for m in model.head if isinstance(m, nn.Linear)]
    assert [(m.in_features, m.out_features) for m in linears] == [(f, w), (w, w), (w, 2)]


@pytest.mark.parametrize("display", list(THESIS_TABLE))
def test_relu_after_every_conv_and_hidden_fc(display):
    layers = [*meta_model(display).features, *meta_model(display).head]
    for i, layer in enumerate(layers[:-1]):
        if isinstance(layer, nn.Conv2d | nn.Linear):
            assert isinstance(layers[i + 1], nn.ReLU), (display, i)
    assert isinstance(layers[-1], nn.Linear)


def test_reconstructed_rows_reach_a_one_by_one_map():
    for display in ("SchoeConv100-V1", "SchoeConv100-V5", "SchoeConv227-V1", "SchoeConv227-V2"):
        size = THESIS_TABLE[display][0]
        maps = meta_model(display).features(torch.zeros(1, 1, size, size, device="meta"))
        assert tuple(maps.shape[2:]) == (1, 1), display


@pytest.mark.parametrize("display", [d for d in THESIS_MACS if d != "AlexNet"])
def test_macs_match_the_thesis(display):
    macs = model_info(display)["macs"]
    assert macs == pytest.approx(THESIS_MACS[display], rel=MACS_RTOL)


def test_alexnet_macs_match_the_thesis_for_its_conv_layers():
    """AlexNet: the thesis's 1.0 G matches the conv layers (1.006 G) to 1 %.

    With its three FC layers (9216*4096 + 4096*4096 + 4096*2 = 54.5 M) the total is 1.061 G,
    6.1 % above the stated figure: the thesis evidently rounded or left the FC head out. We
    check the conv part at the usual 5 % and the total at 7 %.
    """
    model = meta_model("AlexNet")
    total = count_macs(model)
    fc = sum(m.in_features * m.out_features for m in model.head if isinstance(m, nn.Linear))
    assert total - fc == pytest.approx(THESIS_MACS["AlexNet"], rel=MACS_RTOL)
    assert total == pytest.approx(THESIS_MACS["AlexNet"], rel=0.07)
    assert total == 1_060_891_488


def test_macs_by_hand_for_smallconv():
    # conv(5,3,1,20): 75x75 out; conv(4,3,20,40): 8x8 out; FC 360-160-160-2.
    expected = 75 * 75 * 20 * 25 + 8 * 8 * 40 * 20 * 16 + 360 * 160 + 160 * 160 + 160 * 2
    assert model_info("smallconv")["macs"] == expected


def test_macs_count_grouped_convolutions():
    model = nn.Sequential(nn.Conv2d(8, 8, 3, padding=1, groups=8), nn.Conv2d(8, 4, 1))
    model.in_channels, model.input_size = 8, 10
    assert count_macs(model) == 10 * 10 * 8 * 9 + 10 * 10 * 4 * 8


@pytest.mark.parametrize("name", ["smallconv", "resnet-tiny", "mobilenetv2-tiny"])
def test_meta_count_equals_a_real_forward_count(name):
    torch.manual_seed(0)
    real = create_model(name)
    assert count_macs(real) == model_info(name)["macs"]


def test_param_count_matches_a_real_model():
    real = create_model("schoeconv100-v3-fc160", in_channels=3, out_features=4)
    info = model_info("schoeconv100-v3-fc160", in_channels=3, out_features=4)
    assert info["params"] == sum(p.numel() for p in real.parameters())
    assert info["in_channels"] == 3


def test_baselines_are_small_enough_for_a_cpu():
    for name in ("resnet-tiny", "mobilenetv2-tiny"):
        info = model_info(name)
        assert info["input_size"] == 227
        assert info["macs"] < 0.1e9 and info["params"] < 1e6, info


@pytest.mark.parametrize("name", [n for n in list_models() if n not in BIG])
@pytest.mark.parametrize("in_channels", [1, 3])
def test_forward_gives_batch_by_out_features(name, in_channels):
    torch.manual_seed(0)
    model = create_model(name, in_channels=in_channels, out_features=2).eval()
    size = model.input_size
    with torch.no_grad():
        out = model(torch.rand(2, in_channels, size, size))
    assert out.shape == (2, 2)
    assert torch.isfinite(out).all()


@pytest.mark.parametrize("name", sorted(BIG))
def test_big_models_forward_shape_on_meta(name):
    model = meta_model(name, in_channels=3, out_features=4)
    out = model(torch.zeros(2, 3, 227, 227, device="meta"))
    assert out.shape == (2, 4)


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(BIG))
def test_big_models_forward_for_real(name):
    model = create_model(name).eval()
    with torch.no_grad():
        out = model(torch.rand(2, 1, 227, 227))
    assert out.shape == (2, 2)
    assert torch.isfinite(out).all()


def test_four_outputs_for_both_fingers():
    model = create_model("smallconv", out_features=4)
    assert model(torch.rand(2, 1, 227, 227)).shape == (2, 4)


def test_baselines_train_a_step():
    torch.manual_seed(0)
    model = create_model("mobilenetv2-tiny", in_channels=3)
    opt = torch.optim.Adam(model.parameters(), lr=1e-3)
    x, y = torch.rand(2, 3, 96, 96), torch.rand(2, 2)
    loss = nn.functional.mse_loss(model(x), y)
    loss.backward()
    opt.step()
    assert all(torch.isfinite(p).all() for p in model.parameters())


def test_bad_channel_counts_are_rejected():
    with pytest.raises(ValueError, match="in_channels"):
        create_model("smallconv", in_channels=0)


def test_vistac_models_prints_the_table(capsys):
    parser = argparse.ArgumentParser(prog="vistac")
    command.add_command(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["models"])
    assert args.func(args) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].split()[:3] == ["name", "thesis", "name"]
    rows = {line.split()[0]: line for line in out[1:]}
    assert set(list_models()) <= set(rows)
    assert "0.661 G" in rows["schoeconv100-v3-fc160"]
    assert "31.7 G" in rows["schoeconv227-v2"]
    assert rows["alexnet"].split()[-2:] == ["9216", "4096"]
    assert rows["resnet-tiny"].split()[-1] == "-"


def test_vistac_models_is_registered_in_the_cli(capsys):
    from vistac.cli import main

    assert main(["models", "--in-channels", "3"]) == 0
    assert "3-channel" in capsys.readouterr().out
