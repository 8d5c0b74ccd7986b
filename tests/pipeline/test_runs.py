"""blindspot.runs against a real SQLite MLflow store, read back with MlflowClient."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from mlflow.tracking import MlflowClient

from blindspot import runs
from tests.pipeline.toy_repo import clean_env, make_toy_repo, logged_runs


@pytest.fixture(autouse=True)
def _no_outer_tracking_env(monkeypatch: pytest.MonkeyPatch) -> None:
    for key in ("MLFLOW_TRACKING_URI", runs.PARENT_RUN_ENV, "DVC_ROOT", "DVC_EXP_NAME",
                "DVC_EXP_BASELINE_REV", "DVC_STAGE"):
        monkeypatch.delenv(key, raising=False)


@pytest.fixture()
def toy(tmp_path: Path) -> Path:
    return make_toy_repo(tmp_path / "repo")


CFG = {
    "model": {"hidden_size": 16, "layers": [1, 2]},
    "train": {"lr": 0.1, "note": "x" * 7000},
    "runs": {"enabled": True, "uri": None, "experiment": "blindspot"},
    "seed": 0,
}


def _client(root: Path) -> MlflowClient:
    return MlflowClient(tracking_uri=f"sqlite:///{root / 'mlflow.db'}")


def test_stage_run_logs_params_metrics_artifacts(toy: Path) -> None:
    subprocess.run(["git", "init", "-q"], cwd=toy, check=True)
    (toy / "model.pt").write_bytes(b"\x00weights")
    (toy / "figs").mkdir()
    (toy / "figs" / "a.txt").write_text("a")
    with runs.stage_run("train", CFG, repo_root=toy) as t:
        for step in range(3):
            t.log_metrics({"loss": 1.0 / (step + 1), "val": {"rmse_m": 0.5 - 0.1 * step}}, step=step)
        t.log_model_file(toy / "model.pt")
        t.log_artifact(toy / "figs", "figures")
        t.log_params({"train.lr": 0.1})  # same value again: accepted (write-once semantics)
        with pytest.raises(ValueError, match="write-once"):
            t.log_params({"train.lr": 0.2})
        with pytest.raises(ValueError, match="metric 'bad'"):
            t.log_metrics({"bad": "high"})
        t.log_metrics({"cov": {"ci95": [0.8, 0.9]}})     # an interval: one metric per bound
        with pytest.raises(ValueError, match=r"metric 'cov.ci95.1'"):
            t.log_metrics({"cov": {"ci95": [0.8, "x"]}})
        with pytest.raises(FileNotFoundError, match="nope"):
            t.log_artifact(toy / "nope")
        run_id = t.run_id
    client = _client(toy)
    run = client.get_run(run_id)
    assert run.info.status == "FINISHED"
    assert client.get_experiment(run.info.experiment_id).name == "blindspot"
    p = run.data.params
    assert p["model.hidden_size"] == "16" and p["train.lr"] == "0.1" and p["seed"] == "0"
    assert p["model.layers"] == "[1, 2]"
    assert len(p["train.note"]) <= 6000 and "truncated" in p["train.note"]
    assert run.data.tags["blindspot.stage"] == "train"
    assert "mlflow.source.git.commit" not in run.data.tags  # git repo without commits
    assert run.data.metrics["cov.ci95.0"] == 0.8 and run.data.metrics["cov.ci95.1"] == 0.9
    history = client.get_metric_history(run_id, "loss")
    assert [(m.step, round(m.value, 6)) for m in history] == [(0, 1.0), (1, 0.5), (2, 0.333333)]
    assert run.data.metrics["val.rmse_m"] == pytest.approx(0.3)
    names = {a.path for a in client.list_artifacts(run_id)}
    assert names == {"config", "figures", "model"}
    art_root = Path(run.info.artifact_uri.removeprefix("file://"))
    assert art_root.is_relative_to(toy / "mlartifacts")
    assert (art_root / "model" / "model.pt").read_bytes() == b"\x00weights"
    assert (art_root / "figures" / "a.txt").read_text() == "a"
    assert "hidden_size: 16" in (art_root / "config" / "params.yaml").read_text()


def test_git_commit_tag(toy: Path) -> None:
    env = clean_env(GIT_AUTHOR_NAME="t", GIT_AUTHOR_EMAIL="t@t", GIT_COMMITTER_NAME="t",
                    GIT_COMMITTER_EMAIL="t@t")
    for cmd in (["git", "init", "-q"], ["git", "add", "-A"], ["git", "commit", "-qm", "x"]):
        subprocess.run(cmd, cwd=toy, check=True, env=env)
    head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=toy, capture_output=True, text=True,
                          check=True).stdout.strip()
    with runs.stage_run("x", {"a": 1}, repo_root=toy) as t:
        pass
    tags = _client(toy).get_run(t.run_id).data.tags
    assert tags["mlflow.source.git.commit"] == head and tags["git.dirty"] == "false"


def test_exception_ends_run_failed_and_propagates(toy: Path) -> None:
    with pytest.raises(RuntimeError, match="boom"):
        with runs.stage_run("train", CFG, repo_root=toy) as t:
            raise RuntimeError("boom")
    assert _client(toy).get_run(t.run_id).info.status == "FAILED"


def test_nested_stage_runs_get_parent_tag(toy: Path) -> None:
    with runs.stage_run("outer", {"a": 1}, repo_root=toy) as outer:
        with runs.stage_run("inner", {"b": 2}, repo_root=toy, parent_run_id=outer.run_id) as inner:
            pass
    run = _client(toy).get_run(inner.run_id)
    assert run.data.tags["mlflow.parentRunId"] == outer.run_id


def test_disabled_tracking_is_a_no_op(toy: Path) -> None:
    cfg = {"runs": {"enabled": False}, "x": 1}
    (toy / "mlflow.db").unlink()
    with runs.stage_run("train", cfg, repo_root=toy) as t:
        assert t.run_id is None and isinstance(t, runs.NullTracker)
        t.log_metrics({"loss": 1.0})
        t.log_artifact("does-not-matter")
    assert not (toy / "mlflow.db").exists()
    with pytest.raises(ValueError, match="runs.enabled"):
        runs.settings_from_cfg({"runs": {"enabled": "no"}}, toy)


def test_tracking_uri_precedence(toy: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    assert runs.tracking_uri(None, toy) == f"sqlite:///{toy.resolve() / 'mlflow.db'}"
    rel = {"runs": {"uri": "sqlite:///stores/m.db"}}
    assert runs.tracking_uri(rel, toy) == f"sqlite:///{toy.resolve() / 'stores' / 'm.db'}"
    assert runs.tracking_uri({"runs": {"uri": "x.db"}}, toy).endswith(f"{toy.name}/x.db")
    # A `dvc exp run --queue` temp copy logs into the ORIGINAL repo's store.
    copy = make_toy_repo(toy / ".dvc" / "tmp" / "exps" / "tmp1234abcd")
    s = runs.settings_from_cfg(None, copy)
    assert s.uri == f"sqlite:///{toy.resolve() / 'mlflow.db'}"
    assert s.artifact_location == (toy.resolve() / "mlartifacts").as_uri()
    monkeypatch.setenv("MLFLOW_TRACKING_URI", "sqlite:////elsewhere/m.db")
    assert runs.tracking_uri(rel, toy) == "sqlite:////elsewhere/m.db"


def test_job_start_ends_leaked_fluent_run(toy: Path) -> None:
    import mlflow

    mlflow.set_tracking_uri(f"sqlite:///{toy / 'mlflow.db'}")
    try:
        leaked = mlflow.start_run()
        assert mlflow.active_run() is not None
        runs.SweepCallback().on_job_start(config=None)
        assert mlflow.active_run() is None
        assert _client(toy).get_run(leaked.info.run_id).info.status == "FINISHED"
    finally:
        while mlflow.active_run():
            mlflow.end_run()
        mlflow.set_tracking_uri("")


RACE = """
import sys, time
from pathlib import Path
from blindspot import runs
import mlflow.tracking  # the slow imports happen before the barrier
i, n, root = int(sys.argv[1]), int(sys.argv[2]), Path(sys.argv[3])
(root / f"ready-{i}").touch()
while len(list(root.glob("ready-*"))) < n:  # barrier: everybody imported, then go at once
    time.sleep(0.005)
with runs.stage_run("race", {"i": i}, repo_root=root) as t:
    t.log_metrics({"i": i})
"""


def test_parallel_first_runs_on_a_fresh_store_do_not_race(tmp_path: Path) -> None:
    toy = make_toy_repo(tmp_path / "fresh", store=False)
    n = 2  # without the lock, 2 processes on a fresh store already fail (duplicate column)
    procs = [subprocess.Popen([sys.executable, "-c", RACE, str(i), str(n), str(toy)],
                              env=clean_env(), stderr=subprocess.PIPE, text=True)
             for i in range(n)]
    errors = [p.communicate(timeout=240)[1] for p in procs]
    assert [p.returncode for p in procs] == [0] * n, errors
    found = logged_runs(toy)
    assert sorted(int(r.data.params["i"]) for r in found) == list(range(n))
    assert {r.info.status for r in found} == {"FINISHED"}
    assert len(_client(toy).search_experiments()) == 2  # Default + blindspot, created once


def test_sigterm_ends_run_killed_and_leaves_no_partial_file(toy: Path) -> None:
    proc = subprocess.Popen([sys.executable, "-m", "blindspot", "toy", "toy.sleep_s=60"],
                            cwd=toy, env=clean_env(), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 60
    while not (toy / "out" / "started").exists():
        assert proc.poll() is None, proc.communicate()
        assert time.time() < deadline, "toy stage never started"
        time.sleep(0.1)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == 143, err
    (run,) = logged_runs(toy)
    assert run.info.status == "KILLED"
    assert run.info.end_time is not None
    assert "ended KILLED" in err
    # The stage was inside io.atomic_open("out/partial.txt"): nothing half-written remains.
    assert not (toy / "out" / "partial.txt").exists()
    assert [p.name for p in (toy / "out").iterdir() if ".tmp-" in p.name] == []
    # toy.json was written before the signal, in the run's own folder (toy.sleep_s is an
    # override), but a killed stage lands none of its writes (io.all_or_none)
    assert list(toy.glob("outputs/*/*/out")) and not list(toy.glob("outputs/*/*/out/toy.json"))
    assert os.environ.get(runs.PARENT_RUN_ENV) is None


def test_experiment_opens_on_its_runs_not_the_genai_overview(toy: Path) -> None:
    """MLflow 3.x shows an experiment of no declared kind on its GenAI "Overview" (traces) page;
    the experiment is created, and an older one tagged, as a model-development experiment."""
    with runs.stage_run("train", CFG, repo_root=toy):
        pass
    client = _client(toy)
    exp = client.get_experiment_by_name("blindspot")
    assert exp.tags["mlflow.experimentKind"] == "custom_model_development"
    client.delete_experiment_tag(exp.experiment_id, "mlflow.experimentKind")  # a store from before
    with runs.stage_run("train", CFG, repo_root=toy):
        pass
    assert client.get_experiment(exp.experiment_id).tags["mlflow.experimentKind"] == (
        "custom_model_development")


def test_headline_patterns_match_one_dotted_part_per_star(tmp_path: Path) -> None:
    from blindspot.runs.pipeline import headline_metrics

    metrics = {"lstm.val.rmse_m": 0.1, "kalman.val.rmse_m": 0.2, "lstm.per_scene.a.val.rmse_m": 9,
               "lstm.test.rmse_m": 0.3}
    assert headline_metrics("train", metrics, {"train": ["*.val.rmse_m"]}) == {
        "train.lstm.val.rmse_m": 0.1, "train.kalman.val.rmse_m": 0.2}
    assert headline_metrics("evaluate", metrics, {"train": ["*.val.rmse_m"]}) == {}
    with pytest.raises(ValueError, match="runs.headline"):
        runs.settings_from_cfg({"runs": {"headline": {"train": "*.val.rmse_m"}}}, tmp_path)


@pytest.mark.parametrize("enabled", [True, False])
def test_opening_a_store_leaves_the_garbage_collector_as_it_was(tmp_path: Path,
                                                                 enabled: bool) -> None:
    """get_client pauses the cyclic collector while MLflow's store opens (a fifth of a stage's
    import time), then restores it; the store it opened is usable."""
    import gc

    settings = runs.settings_from_cfg({"runs": {"uri": str(tmp_path / "gc.db")}}, tmp_path)
    was = gc.isenabled()
    (gc.enable if enabled else gc.disable)()
    try:
        client = runs.get_client(settings)
        assert gc.isenabled() is enabled
    finally:
        (gc.enable if was else gc.disable)()
    assert [e.name for e in client.search_experiments()] == ["Default"]


@pytest.mark.parametrize("was_enabled", [True, False])
def test_the_collector_pause_restores_the_collector_even_on_an_error(was_enabled):
    """get_client's pause of the cyclic garbage collector: off inside, back as it was after,
    also when the block raises (a store that cannot be opened must not leave the collector off
    for the rest of the stage)."""
    import gc

    from blindspot.runs.store import _gc_paused

    before = gc.isenabled()
    try:
        (gc.enable if was_enabled else gc.disable)()
        with pytest.raises(RuntimeError, match="store"):
            with _gc_paused():
                assert not gc.isenabled()
                raise RuntimeError("store cannot be opened")
        assert gc.isenabled() is was_enabled
        with _gc_paused():
            assert not gc.isenabled()
        assert gc.isenabled() is was_enabled
    finally:
        (gc.enable if before else gc.disable)()


def test_metric_names_from_data_are_cleaned_as_param_names_are(toy: Path) -> None:
    # t3_c18: a recording key "walk (2)" made MLflow refuse the metric and the run end FAILED
    with runs.stage_run("real_tracking", CFG, repo_root=toy) as t:
        t.log_metrics({"walk (2)": {"mota": 0.5, "id switches": 3}})
        t.log_params({"recordings": {"walk (2)": {"path": "x"}}})
        rid = t.run_id
    run = _client(toy).get_run(rid)
    assert run.info.status == "FINISHED"
    assert run.data.metrics == {"walk _2_.mota": 0.5, "walk _2_.id switches": 3.0}
    assert "recordings.walk _2_.path" in run.data.params


def test_infinite_metrics_are_refused_with_a_warning_never_read_back_as_finite(toy: Path) -> None:
    # t3_c17: MLflow's SQL store keeps inf as 1.7976931348623157e308, a finite number
    with runs.stage_run("evaluate", CFG, repo_root=toy) as t:
        with pytest.warns(RuntimeWarning, match=r"'ratio' = inf, 'low' = -inf.*logged as NaN"):
            t.log_metrics({"ratio": float("inf"), "low": -float("inf"), "nan": float("nan"),
                           "ok": 1.0})
        rid = t.run_id
    run = _client(toy).get_run(rid)
    m = run.data.metrics
    assert all(np.isnan(m[k]) for k in ("ratio", "low", "nan")) and m["ok"] == 1.0
    assert run.data.tags["blindspot.metric_inf.ratio"] == "inf"
    assert run.data.tags["blindspot.metric_inf.low"] == "-inf"
