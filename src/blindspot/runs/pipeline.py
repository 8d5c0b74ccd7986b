"""One parent MLflow run per pipeline run (``dvc repro``, ``dvc exp run``, a queued experiment).

DVC runs each stage as its own process (``python stages/<name>.py``), so no process sees the
whole pipeline but DVC's own. That process is found from inside a stage: the nearest ancestor
whose environment lacks ``DVC_STAGE`` (DVC sets it for every stage command, and the shell DVC
starts inherits it). Its host, pid and start time name the pipeline run: the first stage that
runs creates the parent run with those as owner tags (so :mod:`~blindspot.runs.stale`
closes it KILLED if DVC is SIGKILLed), later stages of the same DVC process find it by them.

The parent carries the DVC experiment name (``dvc.exp_name``), the git commit
(``mlflow.source.git.commit``: the experiment's baseline inside an experiment) and, as each stage
ends, that stage's headline metrics (``runs.headline``) as ``<stage>.<metric>``, so two
pipeline runs compare in one view of the runs page; and what the experiment changed: the keys of
params.yaml that differ from what conf/ composes to (``dvc exp run -S`` values), as params and
as the tag ``blindspot.overrides``. Its status follows its stages: RUNNING while
one runs, then the status the last one ended with.
"""

from __future__ import annotations

import contextlib
import fnmatch
import os
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from blindspot.runs.changes import OVERRIDES_TAG, overrides_against_conf, overrides_tag
from blindspot.runs.stale import HOST_TAG, PID_START_TAG, PID_TAG, owner_tags
from blindspot.runs.store import _file_lock, _retry
from blindspot.runs.view import add_to_view

if TYPE_CHECKING:  # pragma: no cover
    from mlflow.tracking import MlflowClient

    from blindspot.runs.store import TrackingSettings

__all__ = ["PIPELINE_TAG", "dvc_process", "pipeline_parent", "headline_metrics",
           "stage_started", "stage_ended"]

PIPELINE_TAG = "blindspot.pipeline"


def _ppid(pid: int) -> int | None:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    return int(stat.rpartition(")")[2].split()[1])


def _has_dvc_stage(pid: int) -> bool | None:
    try:
        env = Path(f"/proc/{pid}/environ").read_bytes()
    except OSError:
        return None
    return any(item.startswith(b"DVC_STAGE=") for item in env.split(b"\0"))


def dvc_process(environ: Mapping[str, str] | None = None) -> int | None:
    """Pid of the DVC process running this stage (``dvc repro`` / ``dvc exp run`` / a queue
    worker), or None outside DVC (no ``DVC_STAGE`` in ``environ``) or where ``/proc`` is
    missing."""
    environ = os.environ if environ is None else environ
    if not environ.get("DVC_STAGE"):
        return None
    pid: int | None = os.getpid()
    for _ in range(64):  # a chain of ancestors, never a cycle; bounded all the same
        pid = _ppid(pid) if pid is not None else None
        if pid is None or pid <= 1:
            return None
        inside = _has_dvc_stage(pid)
        if inside is None:
            return None
        if not inside:
            return pid
    return None


def pipeline_parent(client: MlflowClient, experiment_id: str, settings: TrackingSettings,
                    tags: Mapping[str, str], dvc_pid: int,
                    values: Mapping[str, Any] | None = None,
                    repo_root: str | os.PathLike[str] | None = None) -> str:
    """Id of the parent run of the pipeline run by ``dvc_pid``; created (once, under the store's
    lock) by the first stage, with ``tags`` (git commit, DVC experiment...) and ``dvc_pid`` as
    its owner. On creation, the keys of the config ``values`` (params.yaml) that differ from
    what ``<repo_root>/conf`` composes to (a ``dvc exp run -S`` experiment's values) are logged
    on it as params and as the tag ``blindspot.overrides``
    (:func:`~blindspot.runs.changes.overrides_against_conf`)."""
    owner = owner_tags(dvc_pid)
    query = " and ".join([f"tags.`{PIPELINE_TAG}` = 'true'",
                          *(f"tags.`{k}` = '{owner[k]}'" for k in (HOST_TAG, PID_TAG, PID_START_TAG)
                            if k in owner)])

    def find() -> str | None:
        found = client.search_runs([experiment_id], query, max_results=1)
        return found[0].info.run_id if found else None

    existing = _retry(find, "finding the pipeline's run", counted=False)
    if existing is not None:  # a later stage of the same pipeline run: no composition needed
        return existing
    overrides = _overrides(values, repo_root)

    def find_or_create() -> str:
        found = find()
        if found:
            return found
        keep = ("mlflow.source.git.commit", "git.dirty", "dvc.exp_name", "dvc.baseline_rev",
                "blindspot.repo", "blindspot.workdir")
        run_tags = {k: v for k, v in tags.items() if k in keep}
        exp = tags.get("dvc.exp_name")
        run_tags.update(owner)
        run_tags[PIPELINE_TAG] = "true"
        run_tags["mlflow.source.name"] = "dvc exp run" if exp else "dvc repro"
        run_tags["mlflow.source.type"] = "PROJECT"
        name = f"exp {exp}" if exp else "dvc repro"
        if overrides is not None:
            run_tags[OVERRIDES_TAG] = overrides_tag(overrides)
        run_id = client.create_run(experiment_id, tags=run_tags, run_name=name).info.run_id
        if overrides:
            from mlflow.entities import Param

            client.log_batch(run_id, params=[Param(k, _param_text(v))
                                             for k, v in sorted(overrides.items())])
        return run_id

    with _file_lock(settings.lock_file):  # housekeeping: not a fault point (runs under DVC only)
        return _retry(find_or_create, "finding the pipeline's run", counted=False)


def _param_text(value: Any) -> str:
    import json

    text = json.dumps(value) if isinstance(value, list | dict | bool) or value is None \
        else str(value)
    return text[:6000]


def _overrides(values: Mapping[str, Any] | None, repo_root: str | os.PathLike[str] | None
               ) -> dict[str, Any] | None:
    """The keys of ``values`` that differ from ``<repo_root>/conf``; None when either is
    unknown or conf/ does not compose (the parent then carries no overrides, and says nothing
    wrong)."""
    if values is None or repo_root is None or not (Path(repo_root) / "conf").is_dir():
        return None
    try:
        return overrides_against_conf(values, Path(repo_root) / "conf")
    except Exception as exc:  # noqa: BLE001 - best effort: a parent run without its overrides
        print(f"[blindspot] the pipeline run's overrides against conf/ are unknown: {exc}",
              file=sys.stderr)
        return None


def _matches(name: str, pattern: str) -> bool:
    parts, pats = name.split("."), pattern.split(".")
    return len(parts) == len(pats) and all(fnmatch.fnmatchcase(a, b) for a, b in zip(parts, pats))


def headline_metrics(stage: str, metrics: Mapping[str, float],
                     headline: Mapping[str, Sequence[str]]) -> dict[str, float]:
    """The metrics of ``stage`` named by ``headline[stage]`` (patterns in which ``*`` stands for
    one dotted part of a name: ``*.val.rmse_m`` matches ``lstm.val.rmse_m``, not
    ``lstm.per_scene.x.val.rmse_m``), renamed ``<stage>.<metric>``."""
    patterns = headline.get(stage, ())
    return {f"{stage}.{k}": float(v) for k, v in metrics.items()
            if any(_matches(k, p) for p in patterns)}


def stage_started(client: MlflowClient, parent_run_id: str) -> None:
    """The parent shows RUNNING while one of its stages runs."""
    _retry(lambda: client.update_run(parent_run_id, status="RUNNING"), "reopening the pipeline run",
           counted=False)


def stage_ended(client: MlflowClient, parent_run_id: str, stage: str, child_run_id: str,
                status: str, headline: Mapping[str, Sequence[str]]) -> None:
    """Copy the stage's headline metrics onto the parent, add their columns and the parent's
    params (its overrides) to the runs page's view (:mod:`~blindspot.runs.view`), and end the
    parent with the stage's status (the next stage reopens it)."""
    from mlflow.entities import Metric

    child = client.get_run(child_run_id)
    picked = headline_metrics(stage, child.data.metrics, headline)
    if picked:
        import time

        now = int(time.time() * 1000)
        items = [Metric(k, v, now, 0) for k, v in picked.items()]
        _retry(lambda: client.log_batch(parent_run_id, metrics=items), "logging headline metrics",
               counted=False)
        # the runs page's first view: these metric columns and the parent's changed params
        parent = client.get_run(parent_run_id)
        with contextlib.suppress(Exception):
            add_to_view(client, child.info.experiment_id, metrics=picked,
                        params=sorted(parent.data.params))
    _retry(lambda: client.set_terminated(parent_run_id, status), "ending the pipeline run",
           counted=False)
