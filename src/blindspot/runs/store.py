"""The MLflow store: its URI, one client per URI, the experiment, and retries.

Store: ``MLFLOW_TRACKING_URI`` if set, else ``cfg.runs.uri``, else
``sqlite:///<ABSOLUTE original repo root>/mlflow.db`` with artifacts in ``<repo>/mlartifacts``.
"Original" matters for ``dvc exp run --queue``: DVC runs those in temporary copies under
``<repo>/.dvc/tmp/exps/``; :func:`blindspot.config.original_repo_root` maps them back so every
run lands in the same store. The store and the experiment are created once under a file lock
(parallel jobs on a fresh SQLite file otherwise race on table/experiment creation), and writes
retry while SQLite reports "database is locked".
"""

from __future__ import annotations

import contextlib
import gc
import logging
import os
import time
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

from omegaconf import DictConfig

from blindspot.config import ConfigNotFound, find_repo_root, original_repo_root
from blindspot.io import fault_point
from blindspot.typed_config import plain

if TYPE_CHECKING:  # pragma: no cover
    from mlflow.tracking import MlflowClient

__all__ = [
    "DEFAULT_EXPERIMENT",
    "EXPERIMENT_KIND",
    "EXPERIMENT_KIND_TAG",
    "TrackingSettings",
    "settings_from_cfg",
    "tracking_uri",
    "get_client",
    "ensure_experiment",
]

log = logging.getLogger(__name__)

DEFAULT_EXPERIMENT = "blindspot"
# MLflow 3.x opens an experiment of no declared kind on its GenAI "Overview" (traces) page; this
# kind (the UI's "Machine learning" type) opens it on its runs.
EXPERIMENT_KIND_TAG = "mlflow.experimentKind"
EXPERIMENT_KIND = "custom_model_development"

T = TypeVar("T")


@dataclass(frozen=True)
class TrackingSettings:
    """Where and whether to track. ``artifact_location`` None lets the server decide."""

    enabled: bool
    uri: str
    experiment: str
    artifact_location: str | None
    lock_file: Path | None  # serialises store/experiment creation for local SQLite stores
    # stage -> metric-name patterns copied onto a pipeline's parent run (runs.headline)
    headline: Mapping[str, tuple[str, ...]] = field(default_factory=dict)


def _repo_roots(repo_root: str | os.PathLike[str] | None) -> tuple[Path, Path]:
    """(working copy root, original repo root); falls back to cwd outside a repo."""
    if repo_root is not None:
        work = Path(repo_root).resolve()
    else:
        try:
            work = find_repo_root()
        except ConfigNotFound:
            work = Path.cwd().resolve()
    return work, original_repo_root(work)


def _sqlite_path(uri: str) -> Path | None:
    if uri.startswith("sqlite:///"):
        return Path(uri[len("sqlite:///") :])
    return None


def tracking_uri(
    cfg: DictConfig | Mapping[str, Any] | None = None,
    repo_root: str | os.PathLike[str] | None = None,
) -> str:
    """The tracking URI: env ``MLFLOW_TRACKING_URI`` > ``cfg.runs.uri`` > repo SQLite file.

    A relative SQLite path or a bare ``*.db`` path is made absolute against the ORIGINAL repo
    root (never the cwd: a queued DVC experiment's cwd is a temporary copy).
    """
    _, original = _repo_roots(repo_root)
    section = _plain(cfg).get("runs") if cfg is not None else None
    uri = os.environ.get("MLFLOW_TRACKING_URI") or (
        section.get("uri") if isinstance(section, Mapping) else None)
    if not uri:
        return f"sqlite:///{original / 'mlflow.db'}"
    uri = str(uri)
    if "://" not in uri:
        return f"sqlite:///{(original / uri).resolve()}"
    db = _sqlite_path(uri)
    if db is not None and not db.is_absolute():
        return f"sqlite:///{(original / db).resolve()}"
    return uri


def _plain(cfg: DictConfig | Mapping[str, Any] | None) -> dict[str, Any]:
    """The config as a plain dict (the typed-config layer's conversion; {} for None)."""
    return {} if cfg is None else dict(plain(cfg))


def settings_from_cfg(
    cfg: DictConfig | Mapping[str, Any] | None,
    repo_root: str | os.PathLike[str] | None = None,
) -> TrackingSettings:
    """Read ``cfg.runs`` (enabled, uri, experiment; all optional) into settings."""
    section = _plain(cfg).get("runs") or {}
    if not isinstance(section, Mapping):
        raise ValueError(f"config key 'runs' must be a mapping, found {section!r}")
    enabled = section.get("enabled", True)
    if not isinstance(enabled, bool):
        raise ValueError(f"config key 'runs.enabled' must be true/false, found {enabled!r}")
    experiment = str(section.get("experiment") or DEFAULT_EXPERIMENT)
    headline_cfg = section.get("headline") or {}
    if not isinstance(headline_cfg, Mapping) or not all(
            isinstance(v, list | tuple) and all(isinstance(x, str) for x in v)
            for v in headline_cfg.values()):
        raise ValueError("config key 'runs.headline' must map stage names to lists of metric "
                         f"name patterns (e.g. train: ['*.val.rmse_m']), found {headline_cfg!r}")
    headline = {str(k): tuple(v) for k, v in headline_cfg.items()}
    uri = tracking_uri(cfg, repo_root)
    db = _sqlite_path(uri)
    if db is not None and str(db) != ":memory:":
        artifacts = (db.parent / "mlartifacts").as_uri()
        lock: Path | None = db.with_name(db.name + ".lock")
    else:
        artifacts, lock = None, None
    return TrackingSettings(enabled, uri, experiment, artifacts, lock, headline)


@contextlib.contextmanager
def _file_lock(path: Path | None) -> Iterator[None]:
    if path is None:
        yield
        return
    try:
        import fcntl
    except ImportError:  # pragma: no cover - non-POSIX: fall back to retries only
        yield
        return
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "a+") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


_TRANSIENT = ("database is locked", "unique constraint", "already exists", "integrityerror")


def _retry(fn: Callable[[], T], what: str, attempts: int = 30, *, counted: bool = True) -> T:
    """Call ``fn``; retry (with backoff) on SQLite lock/creation races, re-raise otherwise.

    Each success is a fault point (:func:`blindspot.io.fault_point`) unless ``counted`` is
    False: housekeeping whose calls depend on what earlier runs left behind, so that a stage's
    k-th fault point is the same call in every run."""
    delay = 0.05
    for i in range(attempts):
        try:
            result = fn()
        except Exception as exc:  # noqa: BLE001 - filtered below
            text = f"{type(exc).__name__}: {exc}".lower()
            if i == attempts - 1 or not any(t in text for t in _TRANSIENT):
                raise
            log.debug("retrying %s after %s", what, exc)
            time.sleep(delay)
            delay = min(delay * 1.6, 1.0)
            continue
        if counted:
            fault_point("mlflow", what)  # a test may kill the process after any store call
        return result
    raise AssertionError("unreachable")  # pragma: no cover


_CLIENTS: dict[str, MlflowClient] = {}


@contextlib.contextmanager
def _gc_paused() -> Iterator[None]:
    """Python's cyclic garbage collector paused in the block, then restored as it was.

    Importing MLflow's client and SQLAlchemy store loads ~1,560 modules (after numpy and pandas):
    long-lived classes, functions and ORM tables, next to no garbage. The collector runs every
    700 net allocations (``gc.get_threshold()``) and walks the young objects for cycles each time;
    that is ~20 % of this import's CPU (0.6-0.9 s of 3.4-3.7 s in one process, measured with
    ``benchmarks/bench_stage_overhead.py --gc``; that figure leaves out the first collection
    after the pause, which walks what the block allocated, so the net saving is smaller). In
    :func:`get_client` the pause also covers opening the store under the file lock. Nothing is
    lost: cycles made in the block are collected by the first collection after it."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


def get_client(settings: TrackingSettings) -> MlflowClient:
    """An MlflowClient for ``settings.uri``; a fresh SQLite store is created under the lock.

    The first call of a process imports MLflow's client and store with the cyclic garbage
    collector paused (:func:`_gc_paused`)."""
    client = _CLIENTS.get(settings.uri)
    if client is None:
        with _gc_paused():
            from mlflow.tracking import MlflowClient

            with _file_lock(settings.lock_file):
                client = MlflowClient(tracking_uri=settings.uri)
                # Touch the store so schema creation/migration happens while we hold the lock.
                _retry(lambda: client.search_experiments(max_results=1), "opening the store")
        _CLIENTS[settings.uri] = client
    return client


def ensure_experiment(settings: TrackingSettings) -> str:
    """Id of ``settings.experiment``, created once (race-free across processes) if missing."""
    client = get_client(settings)

    def get_or_create() -> str:
        exp = client.get_experiment_by_name(settings.experiment)
        if exp is not None:
            if exp.lifecycle_stage == "deleted":
                client.restore_experiment(exp.experiment_id)
            return exp.experiment_id
        return client.create_experiment(
            settings.experiment, artifact_location=settings.artifact_location,
            tags={EXPERIMENT_KIND_TAG: EXPERIMENT_KIND},
        )

    with _file_lock(settings.lock_file):
        experiment_id = _retry(get_or_create, f"creating experiment {settings.experiment!r}")
        exp = client.get_experiment(experiment_id)
        if exp.tags.get(EXPERIMENT_KIND_TAG) != EXPERIMENT_KIND:  # a store made before the kind
            _retry(lambda: client.set_experiment_tag(experiment_id, EXPERIMENT_KIND_TAG,
                                                     EXPERIMENT_KIND), "setting the kind",
                   counted=False)
        return experiment_id
