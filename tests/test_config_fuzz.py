"""Config-group fuzzing (issue 9, item 5 of the config part): every typed config built from a
Hydra group, fed out-of-range and wrong-type values key by key, raises only ConfigError naming
the key path (``cfar.guard``), never a bare TypeError / ValueError / numpy error; a value it
accepts is used as given (no "3.5" -> 3); an unknown key is refused with its name.

The groups are enumerated from the code, not listed by hand: every typed config class whose
``GROUP`` is a top-level group is a builder (``cls.from_cfg``), beside the loaders that merge a
group's entries (:data:`LOADERS`); the groups each reads are recorded by calling it once on the
composed config (``profile=tiny``), and every group of the composed config must be read by a
builder or be in :data:`UNTYPED` with the reason; so a new group or a new typed config is fuzzed
without editing this file.
"""

from __future__ import annotations

import functools
import inspect
import math
from collections.abc import Mapping
from dataclasses import fields, is_dataclass
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st
from omegaconf import OmegaConf

import blindspot.safety.config  # noqa: F401  (registers its typed configs)
from blindspot.dsp.config import CfarConfig
from blindspot.radar.config import RadarConfig
from blindspot.radar.scene import load_scenes
from blindspot.radar.scenario import load_scenarios
from blindspot.report.animation import WatchConfig
from blindspot.track.config import tracked_recordings
from blindspot.traj.config import DatasetConfig, PathSpec
from blindspot.typed_config import ConfigError, TypedConfig, jobs

REPO = Path(__file__).resolve().parents[1]

# Groups of the composed config that no typed builder reads, with the reason.
UNTYPED = {
    "recordings": "paths of real captures, read by stages/recordings.py (the capture room)",
    "runs": "MLflow glue settings, read by blindspot.runs (the runner, not the library)",
    "paths": "folders, resolved by blindspot.config.shared_dir / the stage runner",
    "simulate": "one stage switch (write_captures) read by stages/simulate.py",
}

# Values substituted for every key: out of range, wrong type, non-finite, huge.
BAD_VALUES: list[Any] = [
    -1, 0, -0.5, 3.5, -1e300, 1e300, 10**30, -(10**30), float("nan"), float("inf"),
    float("-inf"), "3.5", "3", "", "abc", "channels", None, True, False, [], [1, 2],
    [1.0, float("nan")], ["a", "b"], {"a": 1}, 2**63, 10**400, 0.1, 1,
]


class Recorder:
    """A config stand-in that records which top-level groups a builder reads."""

    def __init__(self, cfg: Mapping):
        self._cfg, self.read = cfg, set()

    def __getattr__(self, key: str) -> Any:
        if key.startswith("_"):
            raise AttributeError(key)
        self.read.add(key)
        return self._cfg[key]

    def __getitem__(self, key: str) -> Any:
        return self.__getattr__(key)


# Builders that are not one class's ``from_cfg``: loaders merging a group's entries, and a
# class placed under a second key (the driving chain's radar and CFAR).
LOADERS = {
    "scenes": lambda cfg: load_scenes(cfg.scene),
    "scenarios": lambda cfg: load_scenarios(cfg.scenario),
    "real_tracking": tracked_recordings,
    "driving_radar": lambda cfg: RadarConfig.from_cfg(cfg, "driving_radar"),
    "driving_cfar": lambda cfg: CfarConfig.from_cfg(cfg, "driving_cfar"),
    "jobs": jobs,
    "watch": WatchConfig.from_cfg,    # the report room's group (the watch stage)
}


def _subclasses(cls: type) -> list[type]:
    return [c for s in cls.__subclasses__() for c in [s, *_subclasses(s)]]


def _builders() -> dict[str, Any]:
    """``from_cfg`` of every typed config class of a top-level group (by group), and
    :data:`LOADERS`."""
    out = {c.GROUP: c.from_cfg for c in _subclasses(TypedConfig)
           if c.GROUP and "." not in c.GROUP and c.__module__.startswith("blindspot.")
           and c.__module__.split(".")[1] not in ("cli", "runs")  # the runner's, not the library's
           and c.GROUP not in ("scene", "scenario")}   # loaded by LOADERS, entries merged
    return {**out, **LOADERS}


BUILDERS = _builders()


@functools.lru_cache(maxsize=1)
def _composed() -> tuple[dict, dict[str, frozenset]]:
    """The composed config (``profile=tiny``) as plain containers, and builder name -> the
    top-level groups it reads (recorded by calling it once)."""
    from blindspot.config import compose

    base = OmegaConf.to_container(compose(["profile=tiny"], config_dir=REPO / "conf"),
                                  resolve=True)
    read = {}
    for name, fn in BUILDERS.items():
        rec = Recorder(base)
        fn(rec)
        read[name] = frozenset(rec.read)
    return base, read


@pytest.fixture()
def base() -> dict:
    return _composed()[0]


@pytest.fixture()
def groups_read() -> dict[str, frozenset]:
    return _composed()[1]


def test_every_group_is_built_by_a_typed_builder_or_listed(base, groups_read):
    assert {"radar", "sim", "cfar", "doa", "detect", "dataset", "model", "train", "ethucy",
            "eval", "scenes"} <= set(BUILDERS)
    covered = set().union(*groups_read.values())
    mappings = {k for k, v in base.items() if isinstance(v, Mapping)}
    assert mappings - covered == set(UNTYPED), (
        "a config group is read by no typed builder: add a TypedConfig class with that GROUP "
        "(or a loader in LOADERS) or list it in UNTYPED with the reason")


def _leaves(node: Any, path: tuple = ()) -> list[tuple]:
    """Key paths of every leaf (and of every list element) of a group's mapping."""
    out = []
    if isinstance(node, Mapping):
        for k, v in node.items():
            out += _leaves(v, path + (k,))
    else:
        out.append(path)
        if isinstance(node, list):
            out += [path + (i,) for i, v in enumerate(node) if not isinstance(v, (Mapping, list))]
    return out


def _set(tree: Any, path: tuple, value: Any) -> Any:
    """A copy of ``tree`` with ``value`` at ``path``; only the containers on the path are
    copied (the builders never modify their input)."""
    if not path:
        return value
    node = list(tree) if isinstance(tree, list) else dict(tree)
    node[path[0]] = _set(tree[path[0]], path[1:], value) if len(path) > 1 else value
    return node


def _dotted(path: tuple) -> str:
    return "".join(f"[{p}]" if isinstance(p, int) else f".{p}" for p in path).lstrip(".")


def _build(fn, cfg: dict) -> Any:
    return fn(Recorder(cfg))


def _check_error(err: ConfigError, path: tuple) -> None:
    """The error names the substituted key, an element of it, or (a rule across keys) a key
    beside it in the same mapping."""
    key, want = err.key, _dotted(path)
    list_path = _dotted(tuple(p for p in path if not isinstance(p, int)))
    parent = _dotted(path[:-1]) if not isinstance(path[-1], int) else _dotted(path[:-2])
    ok = (key in (want, list_path) or key.startswith(want + ".") or key.startswith(want + "[")
          or (key.rsplit(".", 1)[0] == parent and parent)
          or _scene_key_ok(key, path))
    assert ok, f"{want} = ...: ConfigError names {key!r}"
    assert str(err).startswith(f"config key '{key}'") and "expected" in str(err)


def _scene_key_ok(key: str, path: tuple) -> bool:
    """A scene's key under ``scene.shared`` is reported where it lands: ``scene.scenes.<name>``
    followed by the same key path (shared settings are merged into every scene)."""
    if path[:2] != ("scene", "shared"):
        return False
    rest = _dotted(path[2:])
    parts = key.split(".")
    return key.startswith("scene.scenes.") and (
        ".".join(parts[3:]) == rest or ".".join(parts[3:]).startswith(rest)
        or (".".join(parts[3:]).rsplit(".", 1)[0] == rest.rsplit(".", 1)[0]))


def _get(obj: Any, path: tuple) -> Any:
    """The built value at a key path (records in a tuple are found by their name)."""
    for k in path:
        if isinstance(k, int):
            obj = obj[k]
        elif isinstance(obj, Mapping):
            obj = obj[k]
        elif isinstance(obj, tuple) and obj and is_dataclass(obj[0]):
            obj = next(o for o in obj if getattr(o, "name", None) == k)
        else:
            obj = getattr(obj, k)
    return obj


def _same(given: Any, got: Any) -> bool:
    """``got`` is ``given`` as the typed layer converts it (list -> tuple, int -> float) and
    nothing else: no string read as a number, no number truncated, no bool as a number."""
    if isinstance(given, bool) or isinstance(got, bool):
        return type(given) is type(got) and given == got
    if isinstance(given, str):
        return isinstance(got, str) and given == got
    if isinstance(given, (int, float)):
        return (isinstance(got, (int, float)) and not isinstance(got, bool)
                and (got == given or (math.isnan(got) and math.isnan(given)))
                and not (isinstance(given, float) and isinstance(got, int)))
    if isinstance(given, list):
        return (isinstance(got, tuple) and len(got) == len(given)
                and all(_same(a, b) for a, b in zip(given, got)))
    if given is None:
        return True          # null: the key's documented default (e.g. tx_order 0..n_tx-1)
    return True                                  # mappings: checked key by key elsewhere


def _has(tree: Any, path: tuple) -> bool:
    """Whether a key path (or its first key) is set in a scene's own settings."""
    for k in path:
        if isinstance(k, int) or not isinstance(tree, Mapping):
            return True                          # inside a list or record set: the whole value
        if k not in tree:
            return False
        tree = tree[k]
    return True


def _accepted_as_given(built: Any, builder: str, path: tuple, value: Any,
                       scenes_over: Mapping = {}) -> None:
    group, rest = path[0], path[1:]
    if not (isinstance(built, TypedConfig) or builder == "scenes"):
        return                                   # derived objects (array, KalmanCV)
    if builder == "scenes":
        if rest[0] == "scenes":
            name, sub = rest[1], rest[2:]
            if not sub:
                return
            got = _get(built[name], sub)
        else:                                    # shared: a scene not overriding it
            sub = rest[1:]
            own = [n for n, over in scenes_over.items() if not _has(over, sub)]
            if not sub or not own:
                return
            got = _get(built[own[0]], sub)
    else:
        try:
            got = _get(built, rest)
        except (AttributeError, StopIteration):
            return                               # an IGNORED key (e.g. name)
    if isinstance(value, Mapping):
        return
    assert _same(value, got), f"{_dotted(path)} = {value!r} was accepted as {got!r}"


def _group_leaves(base: dict, group: str) -> list[tuple]:
    """The leaves of a group; of ``scene.scenes`` and ``scenario.scenes`` only the first
    scene's that is not null (every scene has the same keys, the builder stops at the first bad
    one, and a null one is left out: the tiny profile drops scenes that way), which keeps the
    test in seconds."""
    firsts = {g: next((n for n, sc in base[g]["scenes"].items() if sc is not None), None)
              for g in ("scene", "scenario") if g in base}
    return [p for p in _leaves(base[group], (group,))
            if not (p[0] in firsts and len(p) > 2 and p[1] == "scenes" and p[2] != firsts[p[0]])]


def _fuzz_group(base, groups_read, group: str, values, paths=None) -> int:
    builders = [b for b, read in groups_read.items() if group in read]
    n = 0
    for path in paths if paths is not None else _group_leaves(base, group):
        for value in values:
            cfg = _set(base, path, value)
            for name in builders:
                try:
                    built = _build(BUILDERS[name], cfg)
                except ConfigError as err:
                    _check_error(err, path)
                    continue
                _accepted_as_given(built, name, path, value, base["scene"]["scenes"])
                n += 1
    return n


def _typed_groups() -> list[str]:
    """Every group some builder reads (composed once, at collection)."""
    return sorted(set().union(*_composed()[1].values()))


@pytest.mark.parametrize("group", _typed_groups())
def test_every_key_of_every_group_refuses_bad_values_with_a_config_error(base, groups_read,
                                                                         group):
    assert any(group in read for read in groups_read.values())
    _fuzz_group(base, groups_read, group, BAD_VALUES)


@pytest.mark.parametrize("group", _typed_groups())
def test_unknown_keys_are_refused_with_their_name(base, groups_read, group):
    builders = [b for b, read in groups_read.items() if group in read]
    mappings = [p for p in _mapping_paths(base[group], (group,))]
    for path in mappings:
        cfg = _set(base, path + ("no_such_key",), 1)
        for name in builders:
            with pytest.raises(ConfigError) as err:
                _build(BUILDERS[name], cfg)
            assert err.value.key.endswith("no_such_key"), err.value.key
            assert "no_such_key" in str(err.value)


def _mapping_paths(node: Any, path: tuple) -> list[tuple]:
    """Key paths of the group and of every mapping inside it."""
    if not isinstance(node, Mapping):
        return []
    return [path] + [p for k, v in node.items() for p in _mapping_paths(v, path + (k,))]


def test_path_spec_alone_refuses_bad_values(base):
    """PathSpec (the kinematics part of the dataset group) built on its own."""
    own = {f.name for f in fields(PathSpec)}
    spec = {k: v for k, v in base["dataset"].items() if k in own}
    PathSpec.from_mapping(spec)
    DatasetConfig.from_mapping(base["dataset"])
    for key in spec:
        for value in BAD_VALUES:
            try:
                got = PathSpec.from_mapping({**spec, key: value}, where="dataset")
            except ConfigError as err:
                assert err.key.startswith("dataset."), err.key
                continue
            assert _same(value, getattr(got, key)), (key, value, getattr(got, key))


ANY_VALUE = st.one_of(
    st.none(), st.booleans(), st.integers(-(2**70), 2**70),
    st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=4),
    st.lists(st.one_of(st.integers(-5, 5), st.floats(-1e3, 1e3), st.text(max_size=2)),
             max_size=4),
    st.dictionaries(st.text(max_size=3), st.integers(), max_size=2))


@given(data=st.data())
def test_random_values_anywhere_give_a_config_error_or_are_used_as_given(data):
    """Hypothesis picks a group, a key and any value (the table above is the systematic part)."""
    base, read = _composed()
    group = data.draw(st.sampled_from(_typed_groups()))
    path = data.draw(st.sampled_from(_leaves(base[group], (group,))))   # any scene
    _fuzz_group(base, read, group, [data.draw(ANY_VALUE)], paths=[path])
