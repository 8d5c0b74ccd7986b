"""Parallel writers into one SQLite MLflow store: a Hydra sweep on the joblib launcher with four
jobs at once, and four queued DVC experiments run two at a time (slow). Nothing may be lost and
nothing may fail with "database is locked": every run ends FINISHED with all its params and its
whole per-epoch metric history.
"""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import pytest
from mlflow.tracking import MlflowClient

from tests.pipeline.test_dvc_tooling import DVC, _wait_for_queue
from tests.pipeline.toy_repo import blindspot, clean_env, make_toy_repo, run, logged_runs

pytestmark = pytest.mark.pipeline

if not DVC.exists() or shutil.which("git") is None:  # pragma: no cover - environment guard
    pytest.skip(f"needs git and {DVC}", allow_module_level=True)

EPOCHS = 40  # per-epoch metric writes per job: many small transactions racing for the lock


def _check_runs(root: Path, found: list, sizes: list[int]) -> None:
    """Each run FINISHED, with its hidden size and EPOCHS steps of the score metric."""
    client = MlflowClient(tracking_uri=f"sqlite:///{root / 'mlflow.db'}")
    assert sorted(int(r.data.params["model.hidden_size"]) for r in found) == sorted(sizes)
    for r in found:
        assert r.info.status == "FINISHED", (r.info.run_name, r.info.status)
        h = int(r.data.params["model.hidden_size"])
        history = client.get_metric_history(r.info.run_id, "score")
        assert [m.step for m in history] == list(range(EPOCHS)), (r.info.run_name, len(history))
        assert history[-1].value == pytest.approx(0.1 * h * EPOCHS)
        assert r.data.metrics["nested.half"] == pytest.approx(0.05 * h)


def test_joblib_sweep_of_four_jobs_at_once_loses_no_run(tmp_path: Path) -> None:
    toy = make_toy_repo(tmp_path / "repo")
    sizes = [1, 2, 3, 4]
    proc = blindspot(["toy", "-m", "hydra/launcher=parallel", "hydra.launcher.n_jobs=4",
                      f"train.epochs={EPOCHS}", f"model.hidden_size={','.join(map(str, sizes))}"],
                     toy, timeout=300)
    assert "database is locked" not in proc.stderr.lower(), proc.stderr[-3000:]
    found = logged_runs(toy)
    (parent,) = [r for r in found if r.data.tags.get("blindspot.sweep") == "true"]
    children = [r for r in found if r is not parent]
    assert parent.info.status == "FINISHED"
    assert {c.data.tags["mlflow.parentRunId"] for c in children} == {parent.info.run_id}
    assert len({c.data.tags["blindspot.pid"] for c in children}) == 4  # four processes at once
    _check_runs(toy, children, sizes)


@pytest.mark.slow  # ~70 s; the default suite's tests/pipeline/test_dvc_tooling.py queues two
def test_dvc_queue_of_four_experiments_two_at_a_time_loses_no_run(tmp_path: Path) -> None:
    root = make_toy_repo(tmp_path / "repo")
    env = clean_env()
    for cmd in (["git", "init", "-q", "-b", "main"], ["git", "config", "user.email", "t@e"],
                ["git", "config", "user.name", "t"]):
        run(cmd, root, env=env)
    run([str(DVC), "init", "-q"], root)
    run([str(DVC), "config", "hydra.enabled", "true"], root)
    small = root / "conf" / "train" / "base.yaml"
    small.write_text(small.read_text().replace("epochs: 2", f"epochs: {EPOCHS}"))
    blindspot(["params"], root)
    run(["git", "add", "-A"], root)
    run(["git", "commit", "-qm", "toy"], root)
    sizes = [5, 6, 7, 8]
    proc = run([str(DVC), "exp", "run", "--queue", "-S",
                f"model.hidden_size={','.join(map(str, sizes))}"], root)
    queued = re.findall(r"Queued experiment '([^']+)'", proc.stdout + proc.stderr)
    assert len(queued) == 4, proc.stdout + proc.stderr
    try:
        run([str(DVC), "queue", "start", "-j", "2"], root)
        status = _wait_for_queue(root, 4, timeout_s=420)
    finally:
        run([str(DVC), "queue", "stop"], root, check=False, timeout=60)
    for name in queued:
        assert re.search(rf"{re.escape(name)}\s+.*Success", status), status
    logs = run([str(DVC), "queue", "logs", queued[0]], root, check=False).stdout
    assert "database is locked" not in logs.lower()
    found = logged_runs(root)
    # each experiment is one pipeline run: a parent run (blindspot.runs.pipeline) and its
    # stage's run nested under it
    stages = [r for r in found if r.data.tags.get("blindspot.stage")]
    parents = {r.info.run_id: r for r in found if not r.data.tags.get("blindspot.stage")}
    assert sorted(r.data.tags["dvc.exp_name"] for r in stages) == sorted(queued)
    assert sorted(r.data.tags["dvc.exp_name"] for r in parents.values()) == sorted(queued)
    for r in stages:
        parent = parents[r.data.tags["mlflow.parentRunId"]]
        assert parent.data.tags["dvc.exp_name"] == r.data.tags["dvc.exp_name"]
    _check_runs(root, stages, sizes)
