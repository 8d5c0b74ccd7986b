"""Hydra multirun: one parent MLflow run per sweep, a nested child run per job.

Each job writes its stage outs into its own job directory (:func:`blindspot.cli.sweep_job_dir`),
never over the pipeline's DVC-tracked outputs; the comparison of the jobs lives in MLflow and, at
the end of the sweep, in ``<sweep dir>/sweep_summary.csv`` (one row per job: job number, run id,
status, overrides, params swept and every metric; also logged as an artifact of the parent run).

:class:`SweepCallback` opens the parent run, named by the kind of sweep
(``train-optuna-<study>``, ``train-submitit-<time>``, ``train-sweep-<time>``:
:func:`~blindspot.runs.changes.sweep_run_name`), with the sweep's overrides as its params and
tag ``blindspot.overrides``, and exports its id in
``BLINDSPOT_MLFLOW_PARENT_RUN_ID``; each job's :func:`blindspot.runs.stage_run` becomes a
nested child of it. Since joblib/loky reuses worker processes, the callback ends any leftover
active run at the start and end of every job.
"""

from __future__ import annotations

import contextlib
import os
import sys
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from hydra.experimental.callback import Callback
from omegaconf import DictConfig, OmegaConf

from blindspot.runs import stage_runs as runs
from blindspot.runs.changes import OVERRIDES_TAG, overrides_tag, parse_overrides, sweep_run_name
from blindspot.runs.stage_runs import PARENT_RUN_ENV
from blindspot.runs.stale import close_stale_runs, owner_tags
from blindspot.runs.store import _repo_roots, _retry, ensure_experiment, get_client, settings_from_cfg
from blindspot.runs.tags import run_tags
from blindspot.runs.view import add_to_view

if TYPE_CHECKING:  # pragma: no cover
    from mlflow.tracking import MlflowClient

__all__ = ["SweepCallback", "end_open_sweep", "write_sweep_summary", "pass_env_to_jobs",
           "SUMMARY_FILE"]


@dataclass
class _OpenSweep:
    client: MlflowClient
    run_id: str
    previous_env: str | None
    sweep_dir: str | None = None


SUMMARY_FILE = "sweep_summary.csv"


def write_sweep_summary(client: MlflowClient, parent_run_id: str, sweep_dir: str | os.PathLike[str]
                        ) -> os.PathLike[str] | None:
    """Write ``<sweep_dir>/sweep_summary.csv``: one row per child run of ``parent_run_id``
    (columns ``job``, ``run_id``, ``status``, ``overrides``, ``out_root``, then every metric by
    name, last value), sorted by Hydra job number; log it to the parent run. None when the sweep
    has no child run."""
    import csv
    import io as _io
    from pathlib import Path

    from blindspot.io import write_text

    children = _retry(lambda: client.search_runs(
        [client.get_run(parent_run_id).info.experiment_id],
        filter_string=f"tags.mlflow.parentRunId = '{parent_run_id}'", max_results=10000),
        "listing the sweep's runs", counted=False)
    if not children:
        return None

    def job(run: Any) -> int:
        num = run.data.tags.get("hydra.job_num", "")
        return int(num) if num.isdigit() else 1 << 30

    children = sorted(children, key=job)
    metrics = sorted({k for r in children for k in r.data.metrics})
    buf = _io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(["job", "run_id", "status", "overrides", "out_root", *metrics])
    for r in children:
        tags = r.data.tags
        writer.writerow([tags.get("hydra.job_num", ""), r.info.run_id, r.info.status,
                         tags.get("hydra.overrides", ""), tags.get("blindspot.out_root", ""),
                         *(r.data.metrics.get(k, "") for k in metrics)])
    path = write_text(Path(sweep_dir) / SUMMARY_FILE, buf.getvalue())
    with contextlib.suppress(Exception):  # the file is the summary; the artifact a convenience
        client.log_artifact(parent_run_id, str(path))
    return path


_SWEEP: _OpenSweep | None = None


def _end_leftover_runs() -> None:
    """End any fluent-API active run a reused (joblib/loky) worker may still hold."""
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
        close_stale_runs(client, [experiment_id])
        tags = {**run_tags(stage, work, original), **owner_tags()}
        tags.pop("hydra.job_num", None)
        tags["blindspot.sweep"] = "true"
        tags["hydra.overrides"] = " ".join(overrides)
        sweep_dir = OmegaConf.select(config, "hydra.sweep.dir", default=None)
        if sweep_dir:
            tags["hydra.sweep_dir"] = str(sweep_dir)
        swept = parse_overrides(overrides)
        tags[OVERRIDES_TAG] = overrides_tag(swept)
        name = sweep_run_name(stage, OmegaConf.select(config, "hydra.sweeper._target_"),
                              OmegaConf.select(config, "hydra.launcher._target_"),
                              OmegaConf.select(config, "hydra.sweeper.study_name"))
        tags["blindspot.sweep_kind"] = name.split("-")[1]
        run = _retry(
            lambda: client.create_run(experiment_id, tags=tags, run_name=name),
            "creating the sweep run",
        )
        if swept:  # what the sweep varies, as params of its parent (write-once: logged here)
            from mlflow.entities import Param

            params = [Param(k, v[:6000]) for k, v in sorted(swept.items())]
            _retry(lambda: client.log_batch(run.info.run_id, params=params),
                   "logging the sweep's overrides")
            with contextlib.suppress(Exception):  # their columns in the runs page's view
                add_to_view(client, experiment_id, params=sorted(swept))
        _SWEEP = _OpenSweep(client, run.info.run_id, os.environ.get(PARENT_RUN_ENV),
                            str(sweep_dir) if sweep_dir else None)
        os.environ[PARENT_RUN_ENV] = run.info.run_id
        # Jobs on Ray or SLURM do not inherit this process's environment: the parent's id and
        # the store travel in each job's own config (hydra.job.env_set, set by Hydra in the job).
        pass_env_to_jobs(config, {PARENT_RUN_ENV: run.info.run_id,
                                  "MLFLOW_TRACKING_URI": settings.uri})

    def on_multirun_end(self, config: DictConfig, **kwargs: Any) -> None:
        sweep = _SWEEP
        if sweep is not None and sweep.sweep_dir:
            path = write_sweep_summary(sweep.client, sweep.run_id, sweep.sweep_dir)
            if path is not None:
                print(f"[blindspot] sweep summary: {path}", file=sys.stderr)
        end_open_sweep("FINISHED")

    def on_job_start(self, config: DictConfig, **kwargs: Any) -> None:
        _end_leftover_runs()

    def on_job_end(self, config: DictConfig, job_return: Any, **kwargs: Any) -> None:
        _end_leftover_runs()


def pass_env_to_jobs(config: DictConfig, env: dict[str, str]) -> None:
    """Have Hydra set ``env`` in every job of the multirun ``config``, whatever the launcher:
    appended to ``hydra.overrides.hydra`` as ``++hydra.job.env_set.KEY='VALUE'``, from which
    Hydra composes each job's config, and which ``run_job`` applies in the job's process (a
    joblib worker, a submitit/SLURM job, a Ray task on another node)."""
    from omegaconf import open_dict, read_write

    with read_write(config), open_dict(config):
        overrides = config.hydra.overrides.hydra
        for key, value in env.items():
            quoted = str(value).replace("\\", "\\\\").replace("'", "\\'")
            overrides.append(f"++hydra.job.env_set.{key}='{quoted}'")


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
