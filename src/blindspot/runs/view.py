"""The runs table's first view: the headline metric columns and the changed params, no clicking.

MLflow's runs page shows, by default, none of a run's metric or param columns (only Source,
Models, Dataset; "Show more columns (778 total)"). It can open on a *shared view*: the page
``#/experiments/<id>/runs?viewStateShareKey=<key>`` reads the experiment tag
``mlflow.sharedViewState.<key>``, a JSON of the table's state (``selectedColumns`` ...). The
pipeline keeps one such view, :data:`VIEW_KEY`, up to date: each time a pipeline's parent run
gets headline metrics or a sweep's parent its overrides, their columns join the view's
(``metrics.`headline.ade_m```, ``params.`train.lr```), headline metrics first. README's MLflow
link (:func:`runs_page_url`) opens it.
"""

from __future__ import annotations

import json
from collections.abc import Iterable
from typing import TYPE_CHECKING

from blindspot.runs.store import _retry

if TYPE_CHECKING:  # pragma: no cover
    from mlflow.tracking import MlflowClient

__all__ = ["VIEW_KEY", "VIEW_TAG", "MAX_COLUMNS", "add_to_view", "runs_page_url", "column"]

VIEW_KEY = "headline"
VIEW_TAG = f"mlflow.sharedViewState.{VIEW_KEY}"
MAX_COLUMNS = 40  # a view is for reading: past this, the oldest param columns leave it


def column(kind: str, name: str) -> str:
    """MLflow's id of a runs-table column: ``metrics.`name``` / ``params.`name```."""
    return f"{kind}.`{name}`"


def runs_page_url(base: str, experiment_id: str) -> str:
    """The runs page of ``experiment_id`` on the server at ``base``, opening on the view."""
    return (f"{base.rstrip('/')}/#/experiments/{experiment_id}/runs?viewStateShareKey={VIEW_KEY}"
            "&workflowType=machine_learning")


def add_to_view(client: MlflowClient, experiment_id: str, *, metrics: Iterable[str] = (),
                params: Iterable[str] = ()) -> None:
    """Add the columns of ``metrics`` and ``params`` (names) to the experiment's view: metric
    columns first, then params, each in the order first added; at most :data:`MAX_COLUMNS`
    (the oldest params dropped first). Best effort: a store that refuses leaves the view as is."""
    def update() -> None:
        exp = client.get_experiment(experiment_id)
        try:
            state = json.loads(exp.tags.get(VIEW_TAG, "{}"))
        except ValueError:
            state = {}
        old = [c for c in state.get("selectedColumns", []) if isinstance(c, str)]
        new_metrics = [column("metrics", m) for m in metrics]
        new_params = [column("params", p) for p in params]
        merged = list(dict.fromkeys([*[c for c in old if c.startswith("metrics.")], *new_metrics,
                                     *[c for c in old if c.startswith("params.")], *new_params]))
        if len(merged) > MAX_COLUMNS:
            n_metrics = sum(c.startswith("metrics.") for c in merged)
            keep_params = max(MAX_COLUMNS - n_metrics, 0)
            param_cols = [c for c in merged if c.startswith("params.")]
            merged = [c for c in merged if c.startswith("metrics.")][:MAX_COLUMNS] + (
                param_cols[len(param_cols) - keep_params:] if keep_params else [])
        if merged == old and VIEW_TAG in exp.tags:
            return
        state["selectedColumns"] = merged
        client.set_experiment_tag(experiment_id, VIEW_TAG, json.dumps(state, sort_keys=True))

    _retry(update, "updating the runs page's view", counted=False)
