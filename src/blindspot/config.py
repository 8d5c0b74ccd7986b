"""Configuration: compose ``conf/`` with Hydra, write and check ``params.yaml``, find the repo.

``conf/`` is the single source of truth; ``params.yaml`` (what DVC tracks) is what it composes
to. ``dvc exp run`` (with ``hydra.enabled``) regenerates params.yaml itself, but ``dvc repro``
does not, so an edit of ``conf/`` alone would silently leave stale parameters:
:func:`check_params` compares the two and raises :class:`ParamsOutOfDate` with the keys that
differ and the command that fixes it.

``params.yaml`` is written exactly as DVC writes it (``OmegaConf.to_yaml`` of the resolved
config, keys in defaults-list order), so ``dvc exp run`` without overrides leaves the file
byte-for-byte unchanged and git shows no churn.

Public API::

    find_repo_root(start=None) -> Path          # working copy: holds conf/config.yaml + dvc.yaml/.dvc
    original_repo_root(root) -> Path            # maps a `dvc exp run --queue` temp copy back
    compose(overrides=(), config_dir=None, config_name="config") -> DictConfig
    to_params_yaml(cfg) -> str
    write_params(repo_root=None) -> Path
    load_params(repo_root=None) -> DictConfig
    params_diff(a, b) -> list[ParamDifference]
    check_params(repo_root=None) -> None        # raises ParamsOutOfDate
    shared_dir(cfg) -> Path                     # ../shared data, also from queue temp copies
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from omegaconf import DictConfig, ListConfig, OmegaConf

__all__ = [
    "CONFIG_DIR",
    "CONFIG_NAME",
    "PARAMS_FILE",
    "FIX_COMMAND",
    "ConfigNotFound",
    "ParamsOutOfDate",
    "ParamDifference",
    "find_repo_root",
    "original_repo_root",
    "compose",
    "to_params_yaml",
    "write_params",
    "load_params",
    "params_diff",
    "flatten",
    "check_params",
    "shared_dir",
]

CONFIG_DIR = "conf"
CONFIG_NAME = "config"
PARAMS_FILE = "params.yaml"
FIX_COMMAND = "python -m blindspot params"

# DVC 3.x runs queued/--temp experiments in mkdtemp() copies under <repo>/.dvc/tmp/exps/.
_DVC_EXP_TMP_PARTS = (".dvc", "tmp", "exps")


class ConfigNotFound(FileNotFoundError):
    """No blindspot repository (conf/config.yaml next to dvc.yaml or .dvc/) was found."""


@dataclass(frozen=True)
class ParamDifference:
    """One dotted key whose value differs between params.yaml and the composition of conf/."""

    key: str
    in_params: Any  # _MISSING when the key is absent
    in_conf: Any

    def __str__(self) -> str:
        def show(v: Any) -> str:
            return "<absent>" if v is _MISSING else repr(v)

        return f"{self.key}: params.yaml has {show(self.in_params)}, conf/ gives {show(self.in_conf)}"


class _Missing:
    def __repr__(self) -> str:
        return "<absent>"


_MISSING: Any = _Missing()


class ParamsOutOfDate(ValueError):
    """params.yaml is not what conf/ composes to."""

    def __init__(self, params_file: Path, differences: Sequence[ParamDifference]):
        self.params_file = params_file
        self.differences = list(differences)
        shown = "\n".join(f"  - {d}" for d in self.differences[:30])
        more = len(self.differences) - 30
        if more > 0:
            shown += f"\n  ... and {more} more"
        super().__init__(
            f"{params_file} is out of date with conf/ ({len(self.differences)} key(s) differ):\n"
            f"{shown}\n"
            f"Fix: run `{FIX_COMMAND}` in {params_file.parent} to regenerate params.yaml from "
            f"conf/ (conf/ is the source of truth; params.yaml is generated). If you meant the "
            f"values now in params.yaml (e.g. after `dvc exp run -S` or `dvc exp apply`), put "
            f"them into conf/ first, then run the command."
        )


# --------------------------------------------------------------------------- repository roots


def _is_repo_root(path: Path) -> bool:
    return (path / CONFIG_DIR / f"{CONFIG_NAME}.yaml").is_file() and (
        (path / "dvc.yaml").is_file() or (path / ".dvc").is_dir()
    )


def find_repo_root(start: str | os.PathLike[str] | None = None) -> Path:
    """The nearest directory at or above ``start`` (default: cwd) that is a blindspot repo.

    A repo root holds ``conf/config.yaml`` and ``dvc.yaml`` (or a ``.dvc/`` directory, before
    the pipeline exists). Returns an absolute, resolved path. This is the *working copy*: inside
    a queued DVC experiment it is the temporary copy; see :func:`original_repo_root`.
    Raises :class:`ConfigNotFound` naming ``start`` otherwise.
    """
    here = Path(start if start is not None else os.getcwd()).resolve()
    if here.is_file():
        here = here.parent
    for candidate in (here, *here.parents):
        if _is_repo_root(candidate):
            return candidate
    raise ConfigNotFound(
        f"no blindspot repository at or above {here}: expected a directory holding "
        f"{CONFIG_DIR}/{CONFIG_NAME}.yaml and dvc.yaml (run from inside the repo)"
    )


def original_repo_root(root: str | os.PathLike[str]) -> Path:
    """Map a DVC experiment temp copy back to the repository it was queued from.

    ``dvc exp run --queue`` / ``--temp`` (DVC 3.x) runs each experiment in a fresh
    ``mkdtemp()`` copy under ``<repo>/.dvc/tmp/exps/tmpXXXXXXXX/`` that lacks git-ignored
    files (mlflow.db, data/...). For such a path the original ``<repo>`` is returned; DVC also
    exports ``DVC_ROOT=<repo>`` to the stage, which is used when it agrees. Any other path is
    returned unchanged (resolved).
    """
    path = Path(root).resolve()
    parts = path.parts
    n = len(_DVC_EXP_TMP_PARTS)
    for i in range(len(parts) - n - 1, -1, -1):
        if parts[i : i + n] == _DVC_EXP_TMP_PARTS:
            candidate = Path(*parts[:i])
            env_root = os.environ.get("DVC_ROOT")
            if env_root and Path(env_root).resolve() != candidate and _is_repo_root(Path(env_root)):
                # DVC says where it came from; trust it over the path pattern.
                return Path(env_root).resolve()
            return candidate
    return path


def shared_dir(cfg: DictConfig | Mapping[str, Any] | None = None) -> Path:
    """Directory of the shared read-only data (``../shared`` next to the repo by default).

    ``BLINDSPOT_SHARED`` wins; else ``cfg.paths.shared_dir`` (relative paths are taken from the
    ORIGINAL repo root, so queued DVC experiments in temp copies still find it).
    """
    env = os.environ.get("BLINDSPOT_SHARED")
    if env:
        return Path(env).resolve()
    rel = "../shared"
    if cfg is not None:
        paths = cfg.get("paths") if isinstance(cfg, Mapping | DictConfig) else None
        if paths is not None and paths.get("shared_dir") is not None:
            rel = str(paths.get("shared_dir"))
    p = Path(rel)
    if not p.is_absolute():
        try:
            base = original_repo_root(find_repo_root())
        except ConfigNotFound:
            base = Path.cwd()
        p = base / p
    return p.resolve()


# --------------------------------------------------------------------------- composition

# Config groups renamed, old top-level key -> new: an override or a params.yaml that names the old
# key fails naming the new one, instead of Hydra's "Key 'tracking' is not in struct".
RENAMED_KEYS = {"tracking": "runs", "benchmark": "walks"}


class RenamedKey(ValueError):
    """A config key that was renamed (:data:`RENAMED_KEYS`), with the new name."""


def check_renamed_keys(keys: Iterable[str], where: str) -> None:
    """Raise :class:`RenamedKey` naming ``where``, the old key and its new name when one of ``keys``
    (overrides such as ``+tracking.uri=x`` or ``benchmark=scene_walks``, or top-level keys) starts
    with a renamed config group."""
    for key in keys:
        head = re.split(r"[.=@]", str(key).lstrip("+~"), maxsplit=1)[0]
        if head in RENAMED_KEYS:
            new = RENAMED_KEYS[head]
            raise RenamedKey(f"{where}: config key {head!r} was renamed {new!r}; found {key!r}, "
                             f"write {new}{str(key).lstrip('+~')[len(head):]} instead")



def compose(
    overrides: Iterable[str] = (),
    config_dir: str | os.PathLike[str] | None = None,
    config_name: str = CONFIG_NAME,
) -> DictConfig:
    """Compose ``config_dir/config_name.yaml`` with Hydra overrides, resolved, without ``hydra``.

    ``config_dir`` defaults to ``<repo root>/conf``. This is the same composition DVC performs
    for ``dvc exp run`` with ``hydra.enabled`` (``initialize_config_dir`` + ``compose`` +
    ``OmegaConf.resolve``). Safe to call inside a running Hydra app (the global Hydra state is
    saved and restored). Raises ``hydra.errors.HydraException`` subclasses for bad overrides.
    """
    from hydra import compose as hydra_compose
    from hydra import initialize_config_dir
    from hydra.core.global_hydra import GlobalHydra
    from hydra.initialize import get_gh_backup, restore_gh_from_backup

    if config_dir is None:
        config_dir = find_repo_root() / CONFIG_DIR
    config_dir = Path(config_dir).resolve()
    overrides = list(overrides)
    check_renamed_keys(overrides, "override")
    if not (config_dir / f"{config_name}.yaml").is_file():
        raise ConfigNotFound(f"{config_dir / (config_name + '.yaml')} does not exist")

    backup = get_gh_backup()
    GlobalHydra.instance().clear()
    try:
        with initialize_config_dir(config_dir=str(config_dir), version_base=None):
            cfg = hydra_compose(config_name=config_name, overrides=list(overrides))
    finally:
        restore_gh_from_backup(backup)
    OmegaConf.resolve(cfg)
    return cfg


def to_params_yaml(cfg: DictConfig | Mapping[str, Any]) -> str:
    """The params.yaml text for ``cfg``: resolved, exactly as ``dvc exp run`` would dump it."""
    node = cfg if isinstance(cfg, DictConfig) else OmegaConf.create(dict(cfg))
    node = OmegaConf.create(OmegaConf.to_container(node, resolve=True))
    return OmegaConf.to_yaml(node)


def write_params(repo_root: str | os.PathLike[str] | None = None) -> Path:
    """(Re)write ``<repo>/params.yaml`` from ``<repo>/conf`` atomically; returns its path."""
    from blindspot.io import write_text

    root = Path(repo_root).resolve() if repo_root is not None else find_repo_root()
    text = to_params_yaml(compose(config_dir=root / CONFIG_DIR))
    target = root / PARAMS_FILE
    if not (target.is_file() and target.read_text(encoding="utf-8") == text):
        write_text(target, text)
    return target


def load_params(repo_root: str | os.PathLike[str] | None = None) -> DictConfig:
    """Read ``<repo>/params.yaml`` (what DVC tracked) as a DictConfig.

    Raises ``FileNotFoundError`` with the fix when the file is absent, ``ValueError`` naming
    the file when it is not a YAML mapping.
    """
    root = Path(repo_root).resolve() if repo_root is not None else find_repo_root()
    path = root / PARAMS_FILE
    if not path.is_file():
        raise FileNotFoundError(
            f"{path} does not exist; generate it from conf/ with `{FIX_COMMAND}`"
        )
    cfg = OmegaConf.load(path)
    if not isinstance(cfg, DictConfig):
        raise ValueError(f"{path}: expected a YAML mapping at top level, found {type(cfg).__name__}")
    check_renamed_keys(cfg.keys(), str(path))
    return cfg


def flatten(cfg: DictConfig | Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """Flatten nested mappings into ``{"a.b.c": value}``; lists stay whole values (plain lists)."""
    if isinstance(cfg, DictConfig | ListConfig):
        cfg = OmegaConf.to_container(cfg, resolve=True)  # type: ignore[assignment]
    out: dict[str, Any] = {}
    for key, value in cfg.items():  # type: ignore[union-attr]
        dotted = f"{prefix}{key}"
        if isinstance(value, Mapping) and value:
            out.update(flatten(value, f"{dotted}."))
        else:
            out[dotted] = value
    return out


def _same(a: Any, b: Any) -> bool:
    # YAML round trips may turn 1.0 into 1.0 and ints stay ints; 1 == 1.0 is accepted, but
    # bool vs int is not (True == 1 in Python).
    if isinstance(a, bool) or isinstance(b, bool):
        return type(a) is type(b) and a == b
    return a == b


def params_diff(
    params: DictConfig | Mapping[str, Any], conf: DictConfig | Mapping[str, Any]
) -> list[ParamDifference]:
    """Keys (dotted) whose values differ between two configs, sorted by key."""
    a, b = flatten(params), flatten(conf)
    return [
        ParamDifference(k, a.get(k, _MISSING), b.get(k, _MISSING))
        for k in sorted(a.keys() | b.keys())
        if k not in a or k not in b or not _same(a[k], b[k])
    ]


def check_params(repo_root: str | os.PathLike[str] | None = None) -> None:
    """Raise :class:`ParamsOutOfDate` if ``params.yaml`` is not what ``conf/`` composes to.

    Values are compared (not text), so key order or YAML style never trips the check.
    """
    root = Path(repo_root).resolve() if repo_root is not None else find_repo_root()
    path = root / PARAMS_FILE
    conf = compose(config_dir=root / CONFIG_DIR)
    if not path.is_file():
        raise ParamsOutOfDate(path, params_diff({}, conf))
    diff = params_diff(load_params(root), conf)
    if diff:
        raise ParamsOutOfDate(path, diff)
