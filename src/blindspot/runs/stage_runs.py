"""Runs: one MLflow run per stage run, and the tracker that logs into it.

Every stage run is wrapped in :func:`stage_run`, which opens an MLflow run, logs the flattened
config as params and a few tags, hands out a :class:`Tracker`, and always closes the run:
FINISHED on success, FAILED on an exception, KILLED on SIGTERM (exit code 143) or Ctrl-C.
A run whose process was SIGKILLed (no handler can run) is closed KILLED when the next run starts
(:mod:`~blindspot.runs.stale`).
The stage runner (:func:`blindspot.cli.run_stage`) is the one caller: it logs what the stage
returns. :func:`current` gives the tracker of the innermost active run (a no-op tracker when none
is active or tracking is disabled).
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import re
import sys
import time
import warnings
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from omegaconf import DictConfig, OmegaConf

from blindspot.config import flatten
from blindspot.io import fault_point
from blindspot.runs import pipeline
from blindspot.runs.changes import parse_overrides, stage_param_keys, stage_params
from blindspot.runs.pipeline import dvc_process, pipeline_parent
from blindspot.runs.signals import Terminated, sigterm_as_exit, sigterm_deferred
from blindspot.runs.stale import close_stale_runs, owner_tags
from blindspot.runs.store import (
    _plain,
    _repo_roots,
    _retry,
    ensure_experiment,
    get_client,
    settings_from_cfg,
)
from blindspot.runs.tags import run_tags

if TYPE_CHECKING:  # pragma: no cover
    from mlflow.tracking import MlflowClient

__all__ = ["PARENT_RUN_ENV", "Tracker", "NullTracker", "stage_run", "current"]

PARENT_RUN_ENV = "BLINDSPOT_MLFLOW_PARENT_RUN_ID"
_PARAM_KEY_OK = re.compile(r"[^0-9A-Za-z_\-. /]")


def _clean_key(key: Any) -> str:
    """A param or metric name MLflow accepts: every character outside letters, digits,
    ``_ - . /`` and blanks replaced by ``_`` (a recording key ``walk (2)`` -> ``walk _2_``), at
    most 250 characters. Names built from data (recording keys, scene names) pass through it."""
    return _PARAM_KEY_OK.sub("_", str(key))[:250]


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
    """(dotted name, number) of every metric: nested mappings under their keys, a list of
    numbers (an interval ``[lo, hi]``) under its indices (``ci95.0``, ``ci95.1``). Names are
    as given; :func:`_loggable` cleans them for MLflow."""
    for key, value in metrics.items():
        name = f"{prefix}{key}"
        if isinstance(value, Mapping):
            yield from _metric_items(value, f"{name}.")
            continue
        if isinstance(value, (list, tuple)):
            yield from _metric_items({str(i): v for i, v in enumerate(value)}, f"{name}.")
            continue
        try:
            number = float(value)
        except (TypeError, ValueError):
            raise ValueError(
                f"metric {name!r}: expected a number, found {type(value).__name__} {value!r}"
            ) from None
        yield name, number


def _loggable(metrics: Mapping[str, Any]) -> tuple[dict[str, float], dict[str, float]]:
    """(the metrics to log, under cleaned names (:func:`_clean_key`); the +-inf ones, by
    cleaned name). MLflow's SQL store writes an infinite value as +-1.8e308 (the largest
    float), which reads back as a finite number; such a value is refused with a warning and
    logged as NaN (no number; the tag of :meth:`Tracker.log_metrics` keeps its sign). NaN is
    stored and read back as NaN."""
    values: dict[str, float] = {}
    infinite: dict[str, float] = {}
    for name, number in _metric_items(metrics):
        clean = _clean_key(name)
        if math.isinf(number):
            infinite[clean] = number
            number = math.nan
        values[clean] = number
    if infinite:
        warnings.warn(
            "metric(s) " + ", ".join(f"{k!r} = {v}" for k, v in infinite.items())
            + ": MLflow would store +-inf as +-1.8e308, a finite number; logged as NaN instead "
            "and tagged blindspot.metric_inf.<name> = inf / -inf", RuntimeWarning, stacklevel=3)
    return values, infinite


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
            name = _clean_key(key)
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
        """Log numeric metrics (nested mappings flattened to dotted keys) at ``step``.

        Names are cleaned as param names are (:func:`_clean_key`: a key built from data, with
        blanks or brackets, must not fail the run). A +-inf value is refused (MLflow would
        read it back as +-1.8e308): a ``RuntimeWarning`` names it, it is logged as NaN and the
        run gets the tag ``blindspot.metric_inf.<name>`` = ``inf`` / ``-inf``. NaN is logged as
        NaN."""
        from mlflow.entities import Metric

        now = int(time.time() * 1000)
        values, infinite = _loggable(metrics)
        if infinite:
            self.set_tags({f"blindspot.metric_inf.{k}": str(v) for k, v in infinite.items()})
        items = [Metric(k, v, now, step or 0) for k, v in values.items()]
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
        fault_point("mlflow", f"logging the artifact {p}")

    def log_model_file(self, path: str | os.PathLike[str], artifact_path: str = "model") -> None:
        """Log a saved model (e.g. a torch checkpoint file or directory) as an artifact."""
        self.log_artifact(path, artifact_path)

    def log_text(self, text: str, artifact_file: str) -> None:
        """Log text as an artifact file."""
        self.client.log_text(self.run_id, text, artifact_file)


_NULL = NullTracker()


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

    Logs as params (dotted keys) the keys of ``cfg`` the stage reads (its ``params:`` in
    ``dvc.yaml``; all of ``cfg`` for a stage dvc.yaml does not know) and the whole resolved config
    as the artifact ``config/params.yaml``; tags: ``blindspot.stage``, git commit (``mlflow.source.git.commit``;
    DVC's baseline rev inside an experiment), ``dvc.exp_name``, ``hydra.job_num``... The run is
    nested under ``parent_run_id``, else under the sweep
    parent named by ``$BLINDSPOT_MLFLOW_PARENT_RUN_ID``, else, for a stage DVC runs, under the
    pipeline run's parent (:mod:`~blindspot.runs.pipeline`), which gets the stage's headline
    metrics (``cfg.runs.headline``) when it ends. Ends FINISHED / FAILED / KILLED
    (SIGTERM -> KILLED and exit status 143); tagged with its owner process, so that a run left
    RUNNING by a SIGKILL is closed KILLED by the next stage_run (:func:`close_stale_runs`).
    With ``cfg.runs.enabled: false`` yields a :class:`NullTracker` and touches no store.
    """
    values = None if cfg is None else _plain(cfg)  # converted once: ~1,300 keys in the pipeline
    settings = settings_from_cfg(values, repo_root)
    if not settings.enabled:
        with sigterm_as_exit():
            yield _NULL
        return

    work, original = _repo_roots(repo_root)
    with sigterm_as_exit():  # from before the run exists: it can never be left RUNNING
        client = get_client(settings)
        tags = {**run_tags(stage, work, original), **owner_tags()}
        pipeline_run_id = None
        if parent_run_id is None:
            parent_run_id = os.environ.get(PARENT_RUN_ENV) or None
        if parent_run_id:
            experiment_id = client.get_run(parent_run_id).info.experiment_id
            close_stale_runs(client, [experiment_id])
        else:
            experiment_id = ensure_experiment(settings)
            close_stale_runs(client, [experiment_id])
            dvc_pid = dvc_process()
            if dvc_pid is not None:  # a stage of `dvc repro` / `dvc exp run`: one parent run
                pipeline_run_id = parent_run_id = pipeline_parent(
                    client, experiment_id, settings, tags, dvc_pid, values, work)
                pipeline.stage_started(client, pipeline_run_id)
        if parent_run_id:
            tags["mlflow.parentRunId"] = parent_run_id
        if run_name is None:
            run_name = stage
            if "hydra.job_num" in tags:
                run_name = f"{stage}#{tags['hydra.job_num']}"
            elif "dvc.exp_name" in tags:
                run_name = f"{stage}@{tags['dvc.exp_name']}"
        with sigterm_deferred():
            run = _retry(
                lambda: client.create_run(experiment_id, tags=tags, run_name=run_name),
                "creating a run",
            )
            tracker = Tracker(client, run.info.run_id)
        error: BaseException | None = None
        try:
            if values is not None:
                # the keys the stage reads (its dvc.yaml params:), not all of the config
                keys = stage_param_keys(work, stage)
                if keys is not None:  # and what a search or an override set on the command line
                    keys = (*keys, "search", *parse_overrides(
                        tags.get("hydra.overrides", "").split()))
                tracker.log_params(stage_params(values, keys))
                tracker.log_text(
                    OmegaConf.to_yaml(cfg, resolve=True) if isinstance(cfg, DictConfig)
                    else OmegaConf.to_yaml(OmegaConf.create(values)), "config/params.yaml")
            yield tracker
        except BaseException as exc:
            error = exc
            raise
        finally:
            status = _status_for(error)
            with sigterm_deferred(), contextlib.suppress(Exception):
                _retry(lambda: client.set_terminated(tracker.run_id, status), "ending the run")
            if pipeline_run_id is not None:
                with sigterm_deferred(), contextlib.suppress(Exception):
                    pipeline.stage_ended(client, pipeline_run_id, stage, tracker.run_id, status,
                                         settings.headline)
            if error is not None and status != "FINISHED":
                print(
                    f"[blindspot] MLflow run {tracker.run_id} ({stage}) ended {status}",
                    file=sys.stderr,
                )
