"""vistac.safe_yaml: numbers as YAML 1.2 reads them, alias expansion bounded, recursion refused."""

from __future__ import annotations

import pytest

from vistac.errors import UserError
from vistac.safe_yaml import MAX_ITEMS, expanded_size, load_yaml


def test_exponent_numbers_are_numbers_and_words_stay_words():
    text = ("a: 1e-2\nb: 1.5e3\nc: -2E+4\nd: .5e1\ne: 1.0\nf: 3\ng: e5\nh: 1e\ni: 12e5x\n"
            "j: '1e-2'\nk: 1.5e+3\n")
    data = load_yaml(text, "t.yaml")
    assert data == {"a": 0.01, "b": 1500.0, "c": -20000.0, "d": 5.0, "e": 1.0, "f": 3, "g": "e5",
                    "h": "1e", "i": "12e5x", "j": "1e-2", "k": 1500.0}
    assert all(type(data[k]) is float for k in "abcdek")


def test_aliases_within_the_bound_load_and_a_bomb_does_not():
    assert load_yaml("a: &x [1, 2]\nb: *x\nc: {<<: {m: 1}, n: 2}\n", "t.yaml") == {
        "a": [1, 2], "b": [1, 2], "c": {"m": 1, "n": 2}}
    bomb = "a: &a [x, x, x, x, x, x, x, x, x, x]\n" + "".join(
        f"{c}: &{c} [*{p}, *{p}, *{p}, *{p}, *{p}, *{p}, *{p}, *{p}, *{p}, *{p}]\n"
        for p, c in zip("abcdef", "bcdefg", strict=True))
    with pytest.raises(UserError, match="t.yaml: expands to 1.23e\\+07 values"):
        load_yaml(bomb, "t.yaml")
    assert expanded_size({"k": list(range(MAX_ITEMS))}) == MAX_ITEMS + 3


def test_recursion_and_deep_nesting_are_one_line_errors():
    with pytest.raises(UserError, match="contains it"):
        load_yaml("a: &a [*a]\n", "t.yaml")
    with pytest.raises(UserError, match="nested too deeply"):
        load_yaml("[" * 5000 + "]" * 5000, "t.yaml")
    with pytest.raises(UserError, match="cannot parse"):
        load_yaml("x: !!python/object/apply:os.system ['true']\n", "t.yaml")


def test_tune_space_files_are_read_safely(tmp_path):
    """`--space` YAML goes through the same reader: 1e-5 is a number, an alias bomb refused."""
    from vistac_learn.tune.space import load_space

    good = tmp_path / "space.yaml"
    good.write_text("params: {lr: {low: 1e-5, high: 1e-2}}\n")
    lr = next(d for d in load_space(good).dims if d.name == "lr")
    assert (lr.low, lr.high) == pytest.approx((1e-5, 1e-2))
    bomb = tmp_path / "bomb.yaml"
    bomb.write_text("a: &a [x, x, x, x, x, x, x, x, x, x]\n"
                    + "".join(f"{c}: &{c} [*{p}, *{p}, *{p}, *{p}, *{p}, *{p}, *{p}, *{p}, *{p},"
                              f" *{p}]\n" for p, c in zip("abcdefgh", "bcdefghi", strict=True)))
    with pytest.raises(UserError, match="--space"):
        load_space(bomb)
