"""One way from a config group to a typed object: frozen dataclasses validated from their fields.

Every room declares its config groups as frozen dataclasses deriving from :class:`TypedConfig`.
Each field says once what it accepts: its type annotation (``int``, ``float``, ``bool``, ``str``,
``X | None``, ``tuple[int, int]``, ``tuple[float, ...]``, a nested config class, or a tuple of
them) and, through :func:`setting`, its range (``ge``/``gt``/``le``/``lt``), its ``choices``,
whether a pair must be ``ordered`` (low <= high) or not all zero (``nonzero``). The same checks run
when a class is built from a config group (:meth:`TypedConfig.from_mapping`) and when code builds
it directly, so no other validation layer is needed. Rules that tie several fields together go in
the class's :meth:`TypedConfig.validate`.

Every failure raises one :class:`ConfigError` naming the dotted config key (``cfar.guard``), the
value found and what is allowed.

Conversions (and nothing else): an OmegaConf node becomes plain containers (interpolations
resolved); a list becomes a tuple; an int becomes a float where a float is declared (only when
exact: an integer beyond 2**53 that a float would round is refused); a mapping
becomes the nested config class of its field; a mapping of records (``{torso: {...}, head:
{...}}``) becomes a tuple of records with ``name`` taken from each key. ``True`` is never an
integer and a float is never an integer.

This module imports nothing of blindspot, so every room (radar at the bottom) may import it.
"""

from __future__ import annotations

import dataclasses
import math
import types
import typing
from collections.abc import Mapping
from dataclasses import MISSING, dataclass, field
from typing import Any, ClassVar, TypeVar

__all__ = ["ConfigError", "Rule", "TypedConfig", "build", "jobs", "setting", "plain"]

T = TypeVar("T", bound="TypedConfig")


class ConfigError(ValueError):
    """A configuration value is missing, unknown or outside its allowed range.

    Attributes:
        key: dotted config key, e.g. ``cfar.guard`` or ``scene.scenes.approach_car.n_frames``.
        value: the value found (None when the key is missing).
        allowed: what the key accepts, in words.
    """

    def __init__(self, key: str, value: Any, allowed: str):
        self.key, self.value, self.allowed = key, value, allowed
        super().__init__(f"config key '{key}' = {value!r} is invalid: expected {allowed}")

    def under(self, prefix: str) -> ConfigError:
        """The same error with its key placed under ``prefix`` (``cfar`` + ``guard``)."""
        if not prefix:
            return self
        if not self.key:
            key = prefix
        elif self.key.startswith("["):
            key = prefix + self.key
        else:
            key = f"{prefix}.{self.key}"
        return ConfigError(key, self.value, self.allowed)


@dataclass(frozen=True)
class Rule:
    """What a field accepts beyond its type. Bounds and choices apply to scalars and to every
    element of a tuple; ``ordered`` and ``nonzero`` to a tuple as a whole; ``min_items`` to a
    variable-length tuple."""

    ge: float | None = None
    gt: float | None = None
    le: float | None = None
    lt: float | None = None
    choices: tuple[Any, ...] | None = None
    ordered: bool = False
    nonzero: bool = False
    min_items: int = 0
    doc: str | None = None


_META = "blindspot.config"


def setting(default: Any = MISSING, *, ge: float | None = None, gt: float | None = None,
            le: float | None = None, lt: float | None = None, choices: Any = None,
            ordered: bool = False, nonzero: bool = False, min_items: int = 0,
            doc: str | None = None, default_factory: Any = MISSING, **field_kwargs: Any) -> Any:
    """A dataclass field with its allowed values (see :class:`Rule`); ``default`` as in
    :func:`dataclasses.field` (omit it for a required key)."""
    rule = Rule(ge=ge, gt=gt, le=le, lt=lt,
                choices=tuple(choices) if choices is not None else None,
                ordered=ordered, nonzero=nonzero, min_items=min_items, doc=doc)
    return field(default=default, default_factory=default_factory,
                 metadata={_META: rule}, **field_kwargs)


def plain(mapping: Any) -> Any:
    """OmegaConf nodes -> plain dicts / lists (interpolations resolved); anything else as is."""
    try:
        from omegaconf import DictConfig, ListConfig, OmegaConf
    except ImportError:  # pragma: no cover - omegaconf is a dependency
        return mapping
    if isinstance(mapping, (DictConfig, ListConfig)):
        return OmegaConf.to_container(mapping, resolve=True)
    return mapping


@dataclass(frozen=True)
class TypedConfig:
    """Base of every typed config class: field checks on construction, :meth:`from_mapping`.

    Class attributes a subclass may set:
        GROUP: the config key used in errors when ``from_mapping`` gets no ``where``.
        IGNORED: keys of the group that this class does not read (e.g. ``name``); any other
            unknown key is an error.
        REQUIRE_ALL: every key must be in the group, even those with a default (for a class
            whose defaults serve code and tests while conf/ is the source of truth).
    """

    GROUP: ClassVar[str] = ""
    IGNORED: ClassVar[tuple[str, ...]] = ()
    REQUIRE_ALL: ClassVar[bool] = False

    def __post_init__(self) -> None:
        hints = _hints(type(self))
        for f in dataclasses.fields(self):
            if not f.init:
                continue
            value = getattr(self, f.name)
            new = _coerce(value, hints[f.name], _rule(f), f.name)
            if new is not value:
                object.__setattr__(self, f.name, new)
        self.validate()

    def validate(self) -> None:
        """Rules across fields; raise :class:`ConfigError` with the field's (relative) key."""

    @classmethod
    def from_mapping(cls: type[T], mapping: Any, where: str | None = None) -> T:
        """Build from a config group (OmegaConf node or mapping); ``where`` (default
        :attr:`GROUP`) prefixes the key in errors.

        Raises:
            ConfigError: unknown key, missing required key, or a value outside its range.
        """
        return build(cls, mapping, cls.GROUP if where is None else where)

    @classmethod
    def from_cfg(cls: type[T], cfg: Any, key: str | None = None) -> T:
        """Build from the composed config ``cfg``: the group at ``key`` (dotted; default
        :attr:`GROUP`), errors naming ``key.<field>``. ``RadarConfig.from_cfg(cfg)`` reads
        ``cfg.radar``; ``RadarConfig.from_cfg(cfg, "driving_radar")`` the same class placed under
        another key. A stage imports the classes it builds, so its import closure (and its
        ``dvc.yaml`` deps) holds only the rooms it reads."""
        key = cls.GROUP if key is None else key
        node = cfg
        for part in key.split("."):
            node = node[part] if isinstance(node, dict) else getattr(node, part)
        return cls.from_mapping(node, key)


def jobs(cfg: Any) -> int:
    """The top-level ``jobs``: worker processes (detect, paths, the driving set, the tracker,
    ETH/UCY) or LSTM inference threads (the stages that roll the scene LSTM out); 1 = in this
    process. Raises ConfigError naming the key for anything but an integer >= 1."""
    value = cfg.jobs
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise ConfigError("jobs", value, "an integer >= 1 (worker processes or threads)")
    return value


def build(cls: type[T], mapping: Any, where: str = "") -> T:
    """``cls`` built from ``mapping``; errors name ``where.key``. See :class:`TypedConfig`."""
    try:
        return _build(cls, mapping)
    except ConfigError as err:
        raise err.under(where) from None


# ----------------------------------------------------------------------------- internals
_HINTS: dict[type, dict[str, Any]] = {}


def _hints(cls: type) -> dict[str, Any]:
    if cls not in _HINTS:
        _HINTS[cls] = typing.get_type_hints(cls)
    return _HINTS[cls]


def _rule(f: dataclasses.Field) -> Rule:
    return f.metadata.get(_META, Rule())


def _build(cls: type, mapping: Any) -> Any:
    m = plain(mapping)
    if m is None:
        m = {}
    if not isinstance(m, Mapping):
        raise ConfigError("", m, f"a mapping of the keys {_field_names(cls)}")
    fields = {f.name: f for f in dataclasses.fields(cls) if f.init}
    ignored = set(getattr(cls, "IGNORED", ()))
    for key in m:
        if key not in fields and key not in ignored:
            raise ConfigError(str(key), m[key], f"one of the keys {sorted(fields)}")
    hints = _hints(cls)
    require_all = getattr(cls, "REQUIRE_ALL", False)
    kwargs = {}
    for name, f in fields.items():
        if name in m:
            kwargs[name] = m[name]
        elif require_all or (f.default is MISSING and f.default_factory is MISSING):
            raise ConfigError(name, None, _describe(hints[name], _rule(f)) + " (the key is required)")
    return cls(**kwargs)


def _field_names(cls: type) -> list[str]:
    return sorted(f.name for f in dataclasses.fields(cls) if f.init)


def _is_config(tp: Any) -> bool:
    return isinstance(tp, type) and dataclasses.is_dataclass(tp)


def _union_args(tp: Any) -> tuple[Any, ...] | None:
    if typing.get_origin(tp) in (typing.Union, types.UnionType):
        return typing.get_args(tp)
    return None


def _coerce(value: Any, tp: Any, rule: Rule, key: str) -> Any:
    """``value`` checked against ``tp`` and ``rule`` and converted (see the module docstring)."""
    value = plain(value)
    args = _union_args(tp)
    if args is not None:
        if value is None and type(None) in args:
            return None
        for alt in (a for a in args if a is not type(None)):
            try:
                return _coerce(value, alt, rule, key)
            except ConfigError as err:
                if _is_config(alt) or _is_config_tuple(alt):
                    raise err
        raise ConfigError(key, value, _describe(tp, rule))
    if tp is Any:
        return value
    if _is_config(tp):
        if isinstance(value, tp):
            return value
        if isinstance(value, Mapping):
            try:
                return _build(tp, value)
            except ConfigError as err:
                raise err.under(key) from None
        raise ConfigError(key, value, f"a mapping of the keys {_field_names(tp)}")
    origin = typing.get_origin(tp)
    if origin is tuple:
        return _coerce_tuple(value, tp, rule, key)
    if origin is dict or tp is dict:
        if not isinstance(value, Mapping):
            raise ConfigError(key, value, "a mapping")
        return dict(value)
    if tp is float and isinstance(value, int) and not isinstance(value, bool) \
            and not _exact_float(value):
        # 10**30 would silently become 1.0000000000000000199e30: refuse rather than round
        raise ConfigError(key, value, _describe(tp, rule) + " (an integer this large has no "
                          "exact float value; write it as a float, e.g. 1e30)")
    if not _scalar_ok(value, tp, rule):
        raise ConfigError(key, value, _describe(tp, rule))
    return float(value) if tp is float else value


def _exact_float(v: int) -> bool:
    """True when the integer ``v`` converts to a float without rounding or overflow."""
    try:
        return float(v) == v
    except OverflowError:
        return False


def _is_config_tuple(tp: Any) -> bool:
    return typing.get_origin(tp) is tuple and any(_is_config(a) for a in typing.get_args(tp))


def _coerce_tuple(value: Any, tp: Any, rule: Rule, key: str) -> tuple:
    items = typing.get_args(tp)
    variable = len(items) == 2 and items[1] is Ellipsis
    elem = items[0] if variable else None
    if variable and _is_config(elem) and isinstance(value, Mapping):
        # a mapping of named records: the key is each record's name
        if len(value) < rule.min_items:
            raise ConfigError(key, value, _describe(tp, rule))
        out = []
        for name, item in value.items():
            item = plain(item)
            if not isinstance(item, Mapping):
                raise ConfigError(f"{key}.{name}", item, f"a mapping of the keys {_field_names(elem)}")
            try:
                out.append(_build(elem, {"name": str(name), **item}))
            except ConfigError as err:
                raise err.under(f"{key}.{name}") from None
        return tuple(out)
    if isinstance(value, (str, bytes, Mapping)) or not isinstance(value, (list, tuple)):
        raise ConfigError(key, value, _describe(tp, rule))
    if (not variable and len(value) != len(items)) or len(value) < rule.min_items:
        raise ConfigError(key, value, _describe(tp, rule))
    out = []
    for i, v in enumerate(value):
        t = elem if variable else items[i]
        if _is_config(t):
            if isinstance(v, t):
                out.append(v)
                continue
            if not isinstance(plain(v), Mapping):
                raise ConfigError(f"{key}[{i}]", v, f"a mapping of the keys {_field_names(t)}")
            try:
                out.append(_build(t, v))
            except ConfigError as err:
                raise err.under(f"{key}[{i}]") from None
            continue
        try:
            out.append(_coerce(v, t, rule, key))
        except ConfigError:
            raise ConfigError(key, value, _describe(tp, rule)) from None
    if rule.ordered and any(a > b for a, b in zip(out, out[1:])):
        raise ConfigError(key, value, _describe(tp, rule))
    if rule.nonzero and all(v == 0 for v in out):
        raise ConfigError(key, value, _describe(tp, rule))
    return tuple(out)


def _scalar_ok(v: Any, tp: Any, rule: Rule) -> bool:
    if tp is bool:
        return isinstance(v, bool)
    if tp is str:
        return isinstance(v, str) and (rule.choices is None or v in rule.choices)
    if tp is int:
        if not isinstance(v, int) or isinstance(v, bool):
            return False
    elif tp is float:
        if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v):
            return False
    else:
        raise TypeError(f"typed_config: unsupported field type {tp!r}")
    if _numeric_choices(rule) and v not in rule.choices:
        return False
    return ((rule.ge is None or v >= rule.ge) and (rule.gt is None or v > rule.gt)
            and (rule.le is None or v <= rule.le) and (rule.lt is None or v < rule.lt))


def _numeric_choices(rule: Rule) -> bool:
    """Choices restrict a number only when they are numbers (``int | str`` with choices
    ``('channels',)`` means: an integer, or the string 'channels')."""
    return rule.choices is not None and all(
        isinstance(c, (int, float)) and not isinstance(c, bool) for c in rule.choices)


def _bounds(rule: Rule) -> str:
    lo = f"[{rule.ge:g}" if rule.ge is not None else f"({rule.gt:g}" if rule.gt is not None else None
    hi = f"{rule.le:g}]" if rule.le is not None else f"{rule.lt:g})" if rule.lt is not None else None
    if lo and hi:
        return f" in {lo}, {hi}"
    if lo:
        return f" {'>=' if lo[0] == '[' else '>'} {lo[1:]}"
    if hi:
        return f" {'<=' if hi[-1] == ']' else '<'} {hi[:-1]}"
    return ""


def _describe(tp: Any, rule: Rule) -> str:
    """What a field accepts, in words (the ``allowed`` part of a ConfigError)."""
    if rule.doc:
        return rule.doc
    args = _union_args(tp)
    if args is not None:
        parts = [_describe(a, Rule(**{**dataclasses.asdict(rule), "doc": None}))
                 for a in args if a is not type(None)]
        text = " or ".join(parts)
        return text + " or null" if type(None) in args else text
    if tp is bool:
        return "true or false"
    if tp is str:
        return f"one of {list(rule.choices)}" if rule.choices is not None else "a string"
    if tp in (int, float):
        if _numeric_choices(rule):
            return f"one of {list(rule.choices)}"
        return ("an integer" if tp is int else "a finite number") + _bounds(rule)
    if _is_config(tp):
        return f"a mapping of the keys {_field_names(tp)}"
    if typing.get_origin(tp) is tuple:
        items = typing.get_args(tp)
        if len(items) == 2 and items[1] is Ellipsis:
            head = "a list" + (f" of at least {rule.min_items}" if rule.min_items else "")
            each = _describe(items[0], Rule(**{**dataclasses.asdict(rule), "ordered": False,
                                                "nonzero": False, "doc": None}))
        else:
            head = f"a list of {len(items)}"
            each = " / ".join(dict.fromkeys(_describe(t, Rule(**{**dataclasses.asdict(rule),
                                                                 "ordered": False, "nonzero": False,
                                                                 "doc": None})) for t in items))
        text = f"{head} items, each {each}"
        if rule.ordered:
            text += ", in increasing order [low, high]"
        if rule.nonzero:
            text += ", not all 0"
        return text
    return repr(tp)
