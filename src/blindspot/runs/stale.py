"""Runs left RUNNING by a process that died without closing them (SIGKILL, OOM killer, power cut).

SIGKILL cannot be caught, so no ``finally`` of :func:`blindspot.runs.stage_run` ends the run.
Every run therefore records who owns it (:func:`owner_tags`: host, pid and the pid's start time,
so a recycled pid is not taken for the owner), and :func:`close_stale_runs` ends KILLED each
RUNNING run whose owner on this host is gone. The stage runner and the sweep callback call it
when a run starts; ``python -m blindspot cleanup`` does it by hand. Runs owned by another
host are left alone: whether their process lives cannot be seen from here.
"""

from __future__ import annotations

import os
import socket
from pathlib import Path
from typing import TYPE_CHECKING

from blindspot.io import _pid_alive
from blindspot.runs.store import _retry, get_client, settings_from_cfg

if TYPE_CHECKING:  # pragma: no cover
    from collections.abc import Mapping
    from typing import Any

    from mlflow.tracking import MlflowClient
    from omegaconf import DictConfig

__all__ = ["HOST_TAG", "PID_TAG", "PID_START_TAG", "CLOSED_TAG", "owner_tags", "close_stale_runs",
           "close_stale_runs_of"]

HOST_TAG = "blindspot.host"
PID_TAG = "blindspot.pid"
PID_START_TAG = "blindspot.pid_start"
CLOSED_TAG = "blindspot.closed_stale"


def _start_time(pid: int) -> str | None:
    """Start time of ``pid`` in clock ticks since boot (``/proc/<pid>/stat`` field 22), or None
    where /proc is missing. Together with the pid it names one process, even after pid reuse."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    # the command name (field 2) may hold spaces or parentheses: split after its last ')'
    return stat.rpartition(")")[2].split()[19]


def owner_tags(pid: int | None = None) -> dict[str, str]:
    """Tags naming process ``pid`` (default: this process) as the owner of a run."""
    pid = os.getpid() if pid is None else pid
    tags = {HOST_TAG: socket.gethostname(), PID_TAG: str(pid)}
    start = _start_time(pid)
    if start is not None:
        tags[PID_START_TAG] = start
    return tags


def _owner_alive(pid: int, start: str | None) -> bool:
    return _pid_alive(pid) and (start is None or _start_time(pid) in (None, start))


def close_stale_runs(client: MlflowClient, experiment_ids: list[str]) -> list[str]:
    """End KILLED every RUNNING run of ``experiment_ids`` owned by a dead process of this host;
    returns their ids. Each gets the tag ``blindspot.closed_stale`` saying who closed it."""
    host = socket.gethostname()
    query = f"attributes.status = 'RUNNING' and tags.`{HOST_TAG}` = '{host}'"
    found = _retry(lambda: client.search_runs(experiment_ids, query, max_results=1000),
                   "searching for stale runs", counted=False)
    closed = []
    for run in found:
        tags = run.data.tags
        pid = tags.get(PID_TAG, "")
        if not pid.isdigit() or _owner_alive(int(pid), tags.get(PID_START_TAG)):
            continue
        note = (f"left RUNNING by process {pid} on {host}, which is gone (killed); "
                f"closed KILLED by process {os.getpid()}")
        _retry(lambda r=run: client.set_tag(r.info.run_id, CLOSED_TAG, note),
               "tagging a stale run", counted=False)
        _retry(lambda r=run: client.set_terminated(r.info.run_id, "KILLED"),
               "closing a stale run", counted=False)
        closed.append(run.info.run_id)
    return closed


def close_stale_runs_of(cfg: DictConfig | Mapping[str, Any] | None,
                        repo_root: str | os.PathLike[str] | None = None) -> list[str]:
    """:func:`close_stale_runs` in the store and experiment ``cfg.runs`` names (what
    ``python -m blindspot cleanup`` does); [] when tracking is off or nothing was run."""
    settings = settings_from_cfg(cfg, repo_root)
    if not settings.enabled:
        return []
    client = get_client(settings)
    experiment = client.get_experiment_by_name(settings.experiment)
    return [] if experiment is None else close_stale_runs(client, [experiment.experiment_id])
