"""MLflow glue: the one package of blindspot that imports mlflow, used only by the stage runner.

A stage returns its metrics and artifacts (:class:`blindspot.cli.StageResult`); the runner
(:func:`blindspot.cli.run_stage`) logs them into the stage's MLflow run. No library room imports
this package (``.importlinter``, contract ``one-door-to-mlflow``).

By concern:

- :mod:`~blindspot.runs.store`: the tracking URI (env ``MLFLOW_TRACKING_URI`` >
  ``cfg.runs.uri`` > ``sqlite:///<original repo root>/mlflow.db``), one client per URI, the
  experiment created once under a file lock, retries while SQLite is locked.
- :mod:`~blindspot.runs.stage_runs`: :func:`stage_run` (one run per stage run, always closed
  FINISHED / FAILED / KILLED), :class:`Tracker` and :class:`NullTracker`.
- :mod:`~blindspot.runs.tags`: git commit, DVC experiment and Hydra job tags of a run.
- :mod:`~blindspot.runs.stale`: runs left RUNNING by a SIGKILLed process, closed KILLED when
  the next run starts (:func:`close_stale_runs`) or by ``python -m blindspot cleanup``.
- :mod:`~blindspot.runs.signals`: SIGTERM -> :class:`Terminated` (exit status 143); forked
  workers die with their stage (:func:`children_die_with_this_process`).
- :mod:`~blindspot.runs.sweep`: :class:`SweepCallback`, Hydra's callback for a multirun (one
  parent run, a nested child per job); ``python -m blindspot`` registers it by the name
  ``blindspot.runs.SweepCallback``. Imported on first use (it imports Hydra, which a DVC
  stage reading params.yaml does not need).
"""

from blindspot.runs.stage_runs import PARENT_RUN_ENV, NullTracker, Tracker, stage_run
from blindspot.runs.signals import Terminated, children_die_with_this_process, sigterm_as_exit
from blindspot.runs.stale import close_stale_runs, close_stale_runs_of
from blindspot.runs.store import (
    DEFAULT_EXPERIMENT,
    TrackingSettings,
    ensure_experiment,
    get_client,
    settings_from_cfg,
    tracking_uri,
)

def __getattr__(name: str):  # PEP 562: Hydra (0.3 s of imports) only for sweeps, not per stage
    if name in ("SweepCallback", "end_open_sweep"):
        from blindspot.runs import sweep

        return getattr(sweep, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


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
    "SweepCallback",
    "end_open_sweep",
    "sigterm_as_exit",
    "children_die_with_this_process",
    "close_stale_runs",
    "close_stale_runs_of",
]
