"""MLflow glue: the one module of blindspot that imports mlflow.

Every stage run is wrapped in :func:`stage_run`, which opens an MLflow run, logs the flattened
config as params and a few tags, hands out a :class:`Tracker`, and always closes the run:
FINISHED on success, FAILED on an exception, KILLED on SIGTERM (exit code 143) or Ctrl-C.
Stage code gets the active tracker with :func:`current` (a no-op tracker when none is active or
tracking is disabled)::

    from blindspot import tracking

    def run(cfg):
        t = tracking.current()
        t.log_metrics({"val_rmse_m": 0.12}, step=epoch)
        t.log_artifact("reports/figures/fig08.png")

Store: ``MLFLOW_TRACKING_URI`` if set, else ``cfg.tracking.uri``, else
``sqlite:///<ABSOLUTE original repo root>/mlflow.db`` with artifacts in ``<repo>/mlartifacts``.
"Original" matters for ``dvc exp run --queue``: DVC runs those in temporary copies under
``<repo>/.dvc/tmp/exps/``; :func:`blindspot.config.original_repo_root` maps them back so every
run lands in the same store. The store and the experiment are created once under a file lock
(parallel jobs on a fresh SQLite file otherwise race on table/experiment creation), and writes
retry while SQLite reports "database is locked".

Hydra multirun (``python -m blindspot <stage> -m ...``): :class:`SweepCallback` opens one parent
run for the sweep and exports its id in ``BLINDSPOT_MLFLOW_PARENT_RUN_ID``; each job's
:func:`stage_run` becomes a nested child of it. Since joblib/loky reuses worker processes, the
callback ends any leftover active run at the start and end of every job.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import re
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

from hydra.experimental.callback import Callback
from omegaconf import DictConfig, OmegaConf

from blindspot.config import ConfigNotFound, find_repo_root, flatten, original_repo_root

if TYPE_CHECKING:  # pragma: no cover
    from mlflow.tracking import MlflowClient

__all__ = [
    "DEFAULT_EXPERIMENT",
    "PARENT_RUN_ENV",
    "Terminated",
    "TrackingSettings",
    "Tracker",
    "NullTracker",
    "settings_from_cfg",
    "tracking_uri",
    "get_client",
    "ensure_experiment",
    "stage_run",
    "current",
    "SweepCallback",
    "end_open_sweep",
    "sigterm_as_exit",
]

log = logging.getLogger(__name__)

DEFAULT_EXPERIMENT = "blindspot"
PARENT_RUN_ENV = "BLINDSPOT_MLFLOW_PARENT_RUN_ID"
_SIGTERM_EXIT = 128 + signal.SIGTERM  # 143
_PARAM_KEY_OK = re.compile(r"[^0-9A-Za-z_\-. /]")

T = TypeVar("T")


class Terminated(SystemExit):
    """Raised inside the process by the SIGTERM handler; exits with status 143."""

    def __init__(self) -> None:
        super().__init__(_SIGTERM_EXIT)


# --------------------------------------------------------------------------- settings / store


@dataclass(frozen=True)
class TrackingSettings:
    """Where and whether to track. ``artifact_location`` None lets the server decide."""

    enabled: bool
    uri: str
    experiment: str
    artifact_location: str | None
    lock_file: Path | None  # serialises store/experiment creation for local SQLite stores


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
    """The tracking URI: env ``MLFLOW_TRACKING_URI`` > ``cfg.tracking.uri`` > repo SQLite file.

    A relative SQLite path or a bare ``*.db`` path is made absolute against the ORIGINAL repo
    root (never the cwd: a queued DVC experiment's cwd is a temporary copy).
    """
    _, original = _repo_roots(repo_root)
    uri = os.environ.get("MLFLOW_TRACKING_URI") or (
        OmegaConf.select(OmegaConf.create(_plain(cfg)), "tracking.uri") if cfg is not None else None
    )
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
    if cfg is None:
        return {}
    if isinstance(cfg, DictConfig):
        return OmegaConf.to_container(cfg, resolve=True)  # type: ignore[return-value]
    return dict(cfg)


def settings_from_cfg(
    cfg: DictConfig | Mapping[str, Any] | None,
    repo_root: str | os.PathLike[str] | None = None,
) -> TrackingSettings:
    """Read ``cfg.tracking`` (enabled, uri, experiment; all optional) into settings."""
    section = _plain(cfg).get("tracking") or {}
    if not isinstance(section, Mapping):
        raise ValueError(f"config key 'tracking' must be a mapping, found {section!r}")
    enabled = section.get("enabled", True)
    if not isinstance(enabled, bool):
        raise ValueError(f"config key 'tracking.enabled' must be true/false, found {enabled!r}")
    experiment = str(section.get("experiment") or DEFAULT_EXPERIMENT)
    uri = tracking_uri(cfg, repo_root)
    db = _sqlite_path(uri)
    if db is not None and str(db) != ":memory:":
        artifacts = (db.parent / "mlartifacts").as_uri()
        lock: Path | None = db.with_name(db.name + ".lock")
    else:
        artifacts, lock = None, None
    return TrackingSettings(enabled, uri, experiment, artifacts, lock)


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


def _retry(fn: Callable[[], T], what: str, attempts: int = 30) -> T:
    """Call ``fn``; retry (with backoff) on SQLite lock/creation races, re-raise otherwise."""
    delay = 0.05
    for i in range(attempts):
        try:
            return fn()
        except Exception as exc:  # noqa: BLE001 - filtered below
            text = f"{type(exc).__name__}: {exc}".lower()
            if i == attempts - 1 or not any(t in text for t in _TRANSIENT):
                raise
            log.debug("retrying %s after %s", what, exc)
            time.sleep(delay)
            delay = min(delay * 1.6, 1.0)
    raise AssertionError("unreachable")  # pragma: no cover


_CLIENTS: dict[str, MlflowClient] = {}


def get_client(settings: TrackingSettings) -> MlflowClient:
    """An MlflowClient for ``settings.uri``; a fresh SQLite store is created under the lock."""
    client = _CLIENTS.get(settings.uri)
    if client is None:
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
            settings.experiment, artifact_location=settings.artifact_location
        )

    with _file_lock(settings.lock_file):
        return _retry(get_or_create, f"creating experiment {settings.experiment!r}")


# --------------------------------------------------------------------------- trackers


def _param_value(value: Any, limit: int) -> str:
    if isinstance(value, list | tuple | dict):
        text = json.dumps(value, sort_keys=True, default=str)
    else:
        text = str(value)
    if len(text) > limit:
        note = f"...[truncated {len(text) - limit + 40} chars]"
        text = text[: limit - len(note)] + note
    return text


def _metric_items(metrics: Mapping[str, Any], prefix: str = "") -> Iterator[tuple[str, float]]:
    for key, value in metrics.items():
        name = f"{prefix}{key}"
        if isinstance(value, Mapping):
            yield from _metric_items(value, f"{name}.")
            continue
        try:
            number = float(value)
        except (TypeError, ValueError):
            raise ValueError(
                f"metric {name!r}: expected a number, found {type(value).__name__} {value!r}"
            ) from None
        yield name, number


class NullTracker:
    """Same interface as :class:`Tracker`; does nothing (tracking disabled / no active run)."""

    run_id: str | None = None
    enabled = False

    def log_params(self, params: Mapping[str, Any]) -> None:
        """Ignored."""

    def log_metrics(self, metrics: Mapping[str, Any], step: int | None = None) -> None:
        """Ignored (values are still validated as numbers)."""
        dict(_metric_items(metrics))

    def log_metric(self, key: str, value: float, step: int | None = None) -> None:
        """Ignored."""

    def set_tags(self, tags: Mapping[str, Any]) -> None:
        """Ignored."""

    def log_artifact(self, path: str | os.PathLike[str], artifact_path: str | None = None) -> None:
        """Ignored."""

    def log_model_file(self, path: str | os.PathLike[str], artifact_path: str = "model") -> None:
        """Ignored."""

    def log_figure(self, figure: Any, artifact_file: str) -> None:
        """Ignored."""

    def log_dict(self, data: Mapping[str, Any], artifact_file: str) -> None:
        """Ignored."""

    def log_text(self, text: str, artifact_file: str) -> None:
        """Ignored."""


class Tracker(NullTracker):
    """Logs into one MLflow run (by id, through MlflowClient; no global active run).

    Params are write-once per run in MLflow: logging an identical value again is a no-op,
    a different value raises ``ValueError`` naming the key and both values.
    """

    enabled = True

    def __init__(self, client: MlflowClient, run_id: str):
        from mlflow.utils.validation import MAX_PARAM_VAL_LENGTH, MAX_PARAMS_TAGS_PER_BATCH

        self.client = client
        self.run_id = run_id
        self._params: dict[str, str] = {}
        self._max_len = MAX_PARAM_VAL_LENGTH
        self._batch = MAX_PARAMS_TAGS_PER_BATCH

    def log_params(self, params: Mapping[str, Any]) -> None:
        """Log (nested mappings flattened to dotted keys) params; long values are truncated."""
        from mlflow.entities import Param

        new: dict[str, str] = {}
        for key, value in flatten(params).items():
            name = _PARAM_KEY_OK.sub("_", str(key))[:250]
            text = _param_value(value, self._max_len)
            old = self._params.get(name, new.get(name))
            if old is None:
                new[name] = text
            elif old != text:
                raise ValueError(
                    f"param {name!r} already logged as {old!r} in run {self.run_id}; MLflow "
                    f"params are write-once (tried {text!r}); log changing values as metrics"
                )
        items = [Param(k, v) for k, v in new.items()]
        for i in range(0, len(items), self._batch):
            chunk = items[i : i + self._batch]
            _retry(lambda c=chunk: self.client.log_batch(self.run_id, params=c), "logging params")
        self._params.update(new)

    def log_metrics(self, metrics: Mapping[str, Any], step: int | None = None) -> None:
        """Log numeric metrics (nested mappings flattened to dotted keys) at ``step``."""
        from mlflow.entities import Metric

        now = int(time.time() * 1000)
        items = [Metric(k, v, now, step or 0) for k, v in _metric_items(metrics)]
        for i in range(0, len(items), 1000):
            chunk = items[i : i + 1000]
            _retry(lambda c=chunk: self.client.log_batch(self.run_id, metrics=c), "logging metrics")

    def log_metric(self, key: str, value: float, step: int | None = None) -> None:
        """Log one metric."""
        self.log_metrics({key: value}, step=step)

    def set_tags(self, tags: Mapping[str, Any]) -> None:
        """Set run tags (values stringified)."""
        from mlflow.entities import RunTag

        items = [RunTag(str(k), str(v)[:8000]) for k, v in tags.items() if v is not None]
        if items:
            _retry(lambda: self.client.log_batch(self.run_id, tags=items), "setting tags")

    def log_artifact(self, path: str | os.PathLike[str], artifact_path: str | None = None) -> None:
        """Copy a file or a whole directory into the run's artifacts (under ``artifact_path``)."""
        p = Path(path)
        if p.is_dir():
            self.client.log_artifacts(self.run_id, str(p), artifact_path)
        elif p.is_file():
            self.client.log_artifact(self.run_id, str(p), artifact_path)
        else:
            raise FileNotFoundError(f"cannot log artifact {p}: no such file or directory")

    def log_model_file(self, path: str | os.PathLike[str], artifact_path: str = "model") -> None:
        """Log a saved model (e.g. a torch checkpoint file or directory) as an artifact."""
        self.log_artifact(path, artifact_path)

    def log_figure(self, figure: Any, artifact_file: str) -> None:
        """Log a matplotlib figure as ``artifact_file`` (e.g. ``"figures/fig08.png"``)."""
        self.client.log_figure(self.run_id, figure, artifact_file)

    def log_dict(self, data: Mapping[str, Any], artifact_file: str) -> None:
        """Log a mapping as a JSON/YAML artifact (format from the suffix)."""
        self.client.log_dict(self.run_id, dict(data), artifact_file)

    def log_text(self, text: str, artifact_file: str) -> None:
        """Log text as an artifact file."""
        self.client.log_text(self.run_id, text, artifact_file)


_STACK: list[NullTracker] = []
_NULL = NullTracker()


def current() -> NullTracker:
    """The tracker of the innermost active :func:`stage_run`, or a no-op tracker."""
    return _STACK[-1] if _STACK else _NULL


# --------------------------------------------------------------------------- run lifecycle


def _git(root: Path, *args: str) -> str | None:
    try:
        out = subprocess.run(
            ["git", *args], cwd=root, capture_output=True, text=True, timeout=10, check=True
        )
    except (OSError, subprocess.SubprocessError):
        return None
    return out.stdout.strip() or None


def _run_tags(stage: str, work: Path, original: Path) -> dict[str, str]:
    tags = {"blindspot.stage": stage, "blindspot.workdir": str(work), "blindspot.repo": str(original)}
    exp_name = os.environ.get("DVC_EXP_NAME")
    baseline = os.environ.get("DVC_EXP_BASELINE_REV")
    if exp_name:
        tags["dvc.exp_name"] = exp_name
    if baseline:
        tags["dvc.baseline_rev"] = baseline
    if os.environ.get("DVC_STAGE"):
        tags["dvc.stage"] = os.environ["DVC_STAGE"]
    commit = baseline or _git(work, "rev-parse", "HEAD")
    if commit:
        tags["mlflow.source.git.commit"] = commit
        dirty = _git(work, "status", "--porcelain", "--untracked-files=no")
        tags["git.dirty"] = "true" if dirty else "false"
    tags["mlflow.source.name"] = f"stages/{stage}.py"
    tags["mlflow.source.type"] = "LOCAL"
    try:
        from hydra.core.hydra_config import HydraConfig

        if HydraConfig.initialized():
            hc = HydraConfig.get()
            if hc.mode is not None and hc.mode.name == "MULTIRUN":
                tags["hydra.job_num"] = str(hc.job.num)
            tags["hydra.overrides"] = " ".join(hc.overrides.task)
    except Exception:  # noqa: BLE001 - tags are best effort
        pass
    return tags


@contextlib.contextmanager
def sigterm_as_exit() -> Iterator[None]:
    """Turn SIGTERM into :class:`Terminated` (SystemExit 143) while the body runs."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum: int, frame: Any) -> None:
        raise Terminated()

    previous = signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


@contextlib.contextmanager
def _sigterm_deferred() -> Iterator[None]:
    """Hold a SIGTERM back while the body runs (a run-state write), then deliver it."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    received: list[int] = []
    previous = signal.signal(signal.SIGTERM, lambda signum, frame: received.append(signum))
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)
        if received:
            if callable(previous):
                previous(signal.SIGTERM, None)
            elif previous != signal.SIG_IGN:
                raise Terminated()


def _status_for(exc: BaseException | None) -> str:
    if exc is None:
        return "FINISHED"
    if isinstance(exc, Terminated | KeyboardInterrupt):
        return "KILLED"
    if isinstance(exc, SystemExit) and exc.code in (0, None):
        return "FINISHED"
    return "FAILED"


@contextlib.contextmanager
def stage_run(
    stage: str,
    cfg: DictConfig | Mapping[str, Any] | None,
    *,
    repo_root: str | os.PathLike[str] | None = None,
    run_name: str | None = None,
    parent_run_id: str | None = None,
) -> Iterator[NullTracker]:
    """Run the body inside one MLflow run for ``stage`` and yield its :class:`Tracker`.

    Logs ``cfg`` flattened as params (dotted keys) and the resolved config as the artifact
    ``config/params.yaml``; tags: ``blindspot.stage``, git commit (``mlflow.source.git.commit``;
    DVC's baseline rev inside an experiment), ``dvc.exp_name``, ``hydra.job_num``... The run is
    nested under ``parent_run_id``, else under an enclosing stage_run, else under the sweep
    parent named by ``$BLINDSPOT_MLFLOW_PARENT_RUN_ID``. Ends FINISHED / FAILED / KILLED
    (SIGTERM -> KILLED and exit status 143). With ``cfg.tracking.enabled: false`` yields a
    :class:`NullTracker` and touches no store.
    """
    settings = settings_from_cfg(cfg, repo_root)
    if not settings.enabled:
        _STACK.append(_NULL)
        try:
            with sigterm_as_exit():
                yield _NULL
        finally:
            _STACK.pop()
        return

    work, original = _repo_roots(repo_root)
    with sigterm_as_exit():  # from before the run exists: it can never be left RUNNING
        client = get_client(settings)
        if parent_run_id is None:
            outer = next((t for t in reversed(_STACK) if t.run_id), None)
            parent_run_id = outer.run_id if outer else os.environ.get(PARENT_RUN_ENV) or None
        if parent_run_id:
            experiment_id = client.get_run(parent_run_id).info.experiment_id
        else:
            experiment_id = ensure_experiment(settings)
        tags = _run_tags(stage, work, original)
        if parent_run_id:
            tags["mlflow.parentRunId"] = parent_run_id
        if run_name is None:
            run_name = stage
            if "hydra.job_num" in tags:
                run_name = f"{stage}#{tags['hydra.job_num']}"
            elif "dvc.exp_name" in tags:
                run_name = f"{stage}@{tags['dvc.exp_name']}"
        with _sigterm_deferred():
            run = _retry(
                lambda: client.create_run(experiment_id, tags=tags, run_name=run_name),
                "creating a run",
            )
            tracker = Tracker(client, run.info.run_id)
            _STACK.append(tracker)
        error: BaseException | None = None
        try:
            if cfg is not None:
                tracker.log_params(_plain(cfg))
                tracker.log_text(
                    OmegaConf.to_yaml(OmegaConf.create(_plain(cfg))), "config/params.yaml"
                )
            yield tracker
        except BaseException as exc:
            error = exc
            raise
        finally:
            _STACK.remove(tracker)
            status = _status_for(error)
            with _sigterm_deferred(), contextlib.suppress(Exception):
                _retry(lambda: client.set_terminated(tracker.run_id, status), "ending the run")
            if error is not None and status != "FINISHED":
                print(
                    f"[blindspot] MLflow run {tracker.run_id} ({stage}) ended {status}",
                    file=sys.stderr,
                )


# --------------------------------------------------------------------------- Hydra multirun


@dataclass
class _OpenSweep:
    client: MlflowClient
    run_id: str
    previous_env: str | None


_SWEEP: _OpenSweep | None = None


def _end_leftover_runs() -> None:
    """End any fluent-API active run a reused (joblib/loky) worker may still hold."""
    _STACK.clear()
    mlflow = sys.modules.get("mlflow")
    if mlflow is not None:
        while mlflow.active_run() is not None:
            mlflow.end_run()


def end_open_sweep(status: str = "FAILED") -> None:
    """Close the sweep's parent run if it is still open (called by the CLI when a sweep dies)."""
    global _SWEEP
    sweep, _SWEEP = _SWEEP, None
    if sweep is None:
        return
    with contextlib.suppress(Exception):
        _retry(lambda: sweep.client.set_terminated(sweep.run_id, status), "ending the sweep")
    if sweep.previous_env is None:
        os.environ.pop(PARENT_RUN_ENV, None)
    else:
        os.environ[PARENT_RUN_ENV] = sweep.previous_env


class SweepCallback(Callback):
    """Hydra callback: one parent MLflow run per multirun, a nested child run per job.

    Registered by ``python -m blindspot`` (``hydra.callbacks.blindspot_tracking``).
    """

    def on_multirun_start(self, config: DictConfig, **kwargs: Any) -> None:
        global _SWEEP
        end_open_sweep("FAILED")
        task_cfg = {k: v for k, v in _plain_with_hydra(config).items() if k != "hydra"}
        settings = settings_from_cfg(task_cfg)
        if not settings.enabled:
            return
        stage = str(OmegaConf.select(config, "hydra.job.name") or "sweep")
        overrides = list(OmegaConf.select(config, "hydra.overrides.task") or [])
        work, original = _repo_roots(None)
        client = get_client(settings)
        experiment_id = ensure_experiment(settings)
        tags = _run_tags(stage, work, original)
        tags.pop("hydra.job_num", None)
        tags["blindspot.sweep"] = "true"
        tags["hydra.overrides"] = " ".join(overrides)
        sweep_dir = OmegaConf.select(config, "hydra.sweep.dir", default=None)
        if sweep_dir:
            tags["hydra.sweep_dir"] = str(sweep_dir)
        run = _retry(
            lambda: client.create_run(experiment_id, tags=tags, run_name=f"{stage}-sweep"),
            "creating the sweep run",
        )
        _SWEEP = _OpenSweep(client, run.info.run_id, os.environ.get(PARENT_RUN_ENV))
        os.environ[PARENT_RUN_ENV] = run.info.run_id

    def on_multirun_end(self, config: DictConfig, **kwargs: Any) -> None:
        end_open_sweep("FINISHED")

    def on_job_start(self, config: DictConfig, **kwargs: Any) -> None:
        _end_leftover_runs()

    def on_job_end(self, config: DictConfig, job_return: Any, **kwargs: Any) -> None:
        _end_leftover_runs()


def _plain_with_hydra(config: DictConfig) -> dict[str, Any]:
    """Resolved container of a config's task part (its hydra node may hold ``${hydra:..}``)."""
    out: dict[str, Any] = {}
    for key in config:
        if key == "hydra":
            continue
        value = config[key]
        if OmegaConf.is_config(value):
            value = OmegaConf.to_container(value, resolve=True)
        out[str(key)] = value
    return out
