"""blindspot.typed_config: a config group onto a frozen dataclass, one ConfigError naming the
dotted key, the value found and the allowed range."""

from __future__ import annotations

import ast
import dataclasses
from dataclasses import dataclass
from pathlib import Path

import pytest
from omegaconf import OmegaConf

import blindspot.typed_config as tc
from blindspot.typed_config import ConfigError, TypedConfig, setting


@dataclass(frozen=True)
class Part(TypedConfig):
    name: str = setting()
    gain_db: float = setting(0.0, ge=-10.0, le=10.0)


@dataclass(frozen=True)
class Inner(TypedConfig):
    size: tuple[int, int] = setting(ge=0, le=8)
    band: tuple[float, float] = setting((0.0, 1.0), ge=0.0, ordered=True)


@dataclass(frozen=True)
class Toy(TypedConfig):
    GROUP = "toy"
    IGNORED = ("name",)

    count: int = setting(ge=1, le=100)
    rate: float = setting(gt=0.0, le=0.5)
    mode: str = setting(choices=("fast", "slow"))
    flag: bool = setting()
    limit: float | None = setting(None, gt=0.0)
    looks: int | str = setting(1, ge=1, choices=("channels",))
    inner: Inner = setting(default_factory=lambda: Inner(size=(1, 1)))
    parts: tuple[Part, ...] = setting((), min_items=0)

    def validate(self) -> None:
        if self.mode == "fast" and self.count > 50:
            raise ConfigError("count", self.count, "at most 50 in mode 'fast'")


GOOD = {"count": 3, "rate": 0.25, "mode": "slow", "flag": True}


def build(**over):
    return Toy.from_mapping({**GOOD, **over})


def error(**over) -> ConfigError:
    with pytest.raises(ConfigError) as err:
        build(**over)
    return err.value


def test_builds_and_converts_from_mapping_and_omegaconf():
    t = Toy.from_mapping(OmegaConf.create({**GOOD, "name": "x", "rate": "${limit}", "limit": 0.5,
                                           "inner": {"size": [2, 3]},
                                           "parts": {"a": {"gain_db": 3}, "b": {}}}))
    assert t.rate == 0.5 and isinstance(t.rate, float) and t.limit == 0.5
    assert t.inner == Inner(size=(2, 3)) and t.inner.band == (0.0, 1.0)
    assert t.parts == (Part("a", 3.0), Part("b", 0.0))
    assert isinstance(t.parts[0].gain_db, float)
    assert dataclasses.is_dataclass(t) and Toy.from_mapping(GOOD) == build()
    with pytest.raises(dataclasses.FrozenInstanceError):
        t.count = 4  # type: ignore[misc]


def test_unknown_key_names_the_key_and_the_known_ones():
    e = error(cuont=3)
    assert e.key == "toy.cuont" and e.value == 3
    assert "'toy.cuont' = 3" in str(e) and "'count'" in str(e)


def test_missing_required_key():
    with pytest.raises(ConfigError) as err:
        Toy.from_mapping({k: v for k, v in GOOD.items() if k != "rate"})
    assert err.value.key == "toy.rate" and err.value.value is None
    assert "(0, 0.5]" in str(err.value) and "required" in str(err.value)


@pytest.mark.parametrize("key,value,allowed", [
    ("count", "3", "an integer in [1, 100]"),           # wrong type
    ("count", 3.0, "an integer in [1, 100]"),           # a float is not an integer
    ("count", True, "an integer in [1, 100]"),          # bool is not int
    ("count", 0, "an integer in [1, 100]"),             # out of range
    ("rate", 0.0, "a finite number in (0, 0.5]"),       # open bound
    ("rate", float("nan"), "a finite number in (0, 0.5]"),
    ("rate", False, "a finite number in (0, 0.5]"),     # bool is not a number
    ("mode", "medium", "one of ['fast', 'slow']"),      # choices
    ("flag", 1, "true or false"),                       # int is not bool
    ("limit", -1.0, "a finite number > 0 or null"),     # optional
    ("looks", 0, "an integer >= 1 or one of ['channels']"),
    ("looks", "all", "an integer >= 1 or one of ['channels']"),
])
def test_bad_value_names_key_value_and_allowed_range(key, value, allowed):
    e = error(**{key: value})
    assert e.key == f"toy.{key}"
    assert e.allowed == allowed
    assert f"'toy.{key}' = {value!r}" in str(e) and allowed in str(e)


def test_optional_null_and_union_choices():
    assert build(limit=None).limit is None
    assert build(looks="channels").looks == "channels" and build(looks=4).looks == 4
    e = error(rate=None)  # not optional: null is refused
    assert e.key == "toy.rate" and "null" not in e.allowed


def test_nested_keys_are_dotted():
    assert error(inner={"size": [1, 9]}).key == "toy.inner.size"
    assert error(inner={"size": [1, 2], "bnd": 1}).key == "toy.inner.bnd"
    e = error(inner={"size": [1, 2], "band": [0.8, 0.2]})
    assert e.key == "toy.inner.band" and "increasing order" in e.allowed
    assert error(inner={"size": [1, 2, 3]}).key == "toy.inner.size"
    assert error(parts={"a": {"gain_db": 30}}).key == "toy.parts.a.gain_db"
    assert error(parts=[{"name": "a", "gain_db": 30}]).key == "toy.parts[0].gain_db"
    assert error(inner=3).key == "toy.inner"


def test_cross_field_rule_and_direct_construction():
    assert error(mode="fast", count=60).key == "toy.count"
    with pytest.raises(ConfigError) as err:
        Toy(count=True, rate=0.1, mode="slow", flag=True)
    assert err.value.key == "count"  # built in code: the key relative to the class
    assert Toy(count=2, rate=0.5, mode="slow", flag=False, limit=2).limit == 2.0
    assert Toy.from_mapping(GOOD, where="other").count == 3
    with pytest.raises(ConfigError, match="'other.count'"):
        Toy.from_mapping({**GOOD, "count": 0}, where="other")


def test_require_all_makes_defaults_code_only():
    @dataclass(frozen=True)
    class Strict(Inner):
        REQUIRE_ALL = True

    assert Inner.from_mapping({"size": [1, 2]}).band == (0.0, 1.0)
    assert Strict(size=(1, 2)).band == (0.0, 1.0)  # built in code, the default holds
    with pytest.raises(ConfigError) as err:
        Strict.from_mapping({"size": [1, 2]}, where="g")
    assert err.value.key == "g.band" and "required" in err.value.allowed


def test_not_a_mapping():
    with pytest.raises(ConfigError) as err:
        Toy.from_mapping([1, 2])
    assert err.value.key == "toy" and "a mapping" in err.value.allowed


def test_helper_module_imports_nothing_of_blindspot():
    """Every room (radar is the bottom one) imports it, so it must sit below all of them."""
    tree = ast.parse(Path(tc.__file__).read_text())
    imported = [n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)]
    imported += [a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names]
    assert not [m for m in imported if m and m.split(".")[0] == "blindspot"]


def test_a_large_integer_is_not_rounded_into_a_float_field():
    """10**30 has no exact float: refused with the reason rather than stored as 1.0000000000000000199e30
    (the config fuzzing found this in every float key); an exact integer is still converted."""
    @dataclass(frozen=True)
    class Big(TypedConfig):
        x: float = setting(ge=0.0)

    assert Big(x=2**53).x == float(2**53)
    for value in (10**30, 2**53 + 1, 10**400):
        with pytest.raises(ConfigError) as err:
            Big.from_mapping({"x": value}, where="g")
        assert err.value.key == "g.x" and "no exact float" in err.value.allowed
