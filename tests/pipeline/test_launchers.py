"""The sweep engines beside the joblib launcher (issue 13): Hydra's submitit launcher (the local
twin of its SLURM launcher) and Hydra's Optuna sweeper, each through ``python -m blindspot``.

Each job of a sweep is its own MLflow run, nested under the sweep's (study's) parent run, with
its params and metrics; the sweep's directory holds ``sweep_summary.csv``. The Ray launcher
and the PostgreSQL tracking server have their own, slow, tests (tests/slow/).
"""

from __future__ import annotations

import csv
import shutil
from pathlib import Path

import pytest

from tests.conftest import REPO_ROOT
from tests.pipeline.test_sweep_outputs import copy_code, synthetic_windows
from tests.pipeline.toy_repo import blindspot, make_toy_repo, logged_runs



def needs(plugin: str) -> None:
    pytest.importorskip(f"hydra_plugins.{plugin}", reason="the cluster extra: make setup-cluster")


def sweep_runs(root: Path) -> tuple[object, list]:
    """The one sweep parent of ``root``'s store and its children by job number."""
    found = logged_runs(root)
    parents = [r for r in found if r.data.tags.get("blindspot.sweep") == "true"]
    assert len(parents) == 1, [r.info.run_name for r in found]
    children = [r for r in found if r.data.tags.get("mlflow.parentRunId") == parents[0].info.run_id]
    return parents[0], sorted(children, key=lambda r: int(r.data.tags["hydra.job_num"]))


@pytest.mark.slow  # ~25 s on an idle 2-core machine (two job processes + the launcher)
def test_submitit_local_two_job_sweep(tmp_path: Path) -> None:
    needs("hydra_submitit_launcher")
    root = make_toy_repo(tmp_path / "repo")
    shutil.copy(REPO_ROOT / "conf" / "hydra" / "launcher" / "submitit.yaml",
                root / "conf" / "hydra" / "launcher")
    blindspot(["toy", "-m", "hydra/launcher=submitit", "hydra.launcher.cpus_per_task=1",
               "hydra.sweep.dir=multirun/s", "model.hidden_size=8,32"], root, timeout=300)
    parent, children = sweep_runs(root)
    assert parent.info.status == "FINISHED"
    assert [r.data.params["model.hidden_size"] for r in children] == ["8", "32"]
    assert [r.data.metrics["score"] for r in children] == pytest.approx([1.6, 6.4])  # 2 x lr x h
    assert all(r.info.status == "FINISHED" for r in children)
    # submitit ran each job in its own process, not in the launching one
    pids = {r.data.tags["toy.pid"] for r in children}
    assert len(pids) == 2 and parent.data.tags["blindspot.pid"] not in pids
    assert (root / "multirun/s/.submitit").is_dir()
    for job in (0, 1):  # the job directories, not the repo's out/, got the outputs
        assert (root / f"multirun/s/{job}/out/toy.json").is_file()
    assert not (root / "out" / "toy.json").exists()


@pytest.mark.slow  # ~45 s on an idle 2-core machine (two studies of two 1-epoch trainings)
def test_optuna_two_trial_study_nested_under_its_parent(tmp_path: Path) -> None:
    needs("hydra_optuna_sweeper")
    import optuna

    root = copy_code(tmp_path / "repo")
    synthetic_windows(root, window=50)
    args = ["train", "-m", "+search=lstm", "hydra.sweeper.n_trials=2", "profile=tiny",
            "train.epochs=1", "train.val_horizon_frames=5", "progress=false", "jobs=1"]
    blindspot([*args, "hydra.sweep.dir=multirun/study"], root, timeout=300)
    parent, trials = sweep_runs(root)
    assert parent.info.status == "FINISHED" and len(trials) == 2
    for r in trials:
        assert r.info.status == "FINISHED"
        assert {"model.hidden_size", "model.num_layers", "train.lr", "train.batch_size"} <= set(
            r.data.params)
        assert 1e-4 <= float(r.data.params["train.lr"]) <= 1e-2
        assert r.data.params["search.objective"] == "lstm.val.ade_m"
        assert r.data.metrics["lstm.val.ade_m"] > 0 and r.data.metrics["lstm.val.n_windows"] > 0
    study = root / "multirun" / "study"
    best = (study / "optimization_results.yaml").read_text()
    best_value = min(r.data.metrics["lstm.val.ade_m"] for r in trials)
    assert f"best_value: {best_value}" in best  # the sweeper got each trial's objective
    with open(study / "sweep_summary.csv", newline="") as fh:
        assert [row["run_id"] for row in csv.DictReader(fh)] == [r.info.run_id for r in trials]

    # the study is stored: a second search with the same name continues it (2 + 2 trials)
    storage = f"sqlite:///{root / 'optuna.db'}"
    assert len(optuna.load_study(study_name="lstm", storage=storage).trials) == 2
    blindspot([*args, "hydra.sweep.dir=multirun/study2"], root, timeout=300)
    stored = optuna.load_study(study_name="lstm", storage=storage)
    assert [t.state.name for t in stored.trials] == ["COMPLETE"] * 4
    assert sorted(t.value for t in stored.trials[:2]) == sorted(
        r.data.metrics["lstm.val.ade_m"] for r in trials)


def test_search_objective_not_a_metric_names_the_key() -> None:
    from blindspot.cli import objective_value
    from blindspot.stage import StageResult

    result = StageResult(metrics={"lstm": {"val": {"rmse_m": 0.2}}})
    assert objective_value(result, "lstm.val.rmse_m", "train") == 0.2
    with pytest.raises(KeyError, match=r"search.objective.*lstm.val.ade.*lstm.val.rmse_m"):
        objective_value(result, "lstm.val.ade", "train")


@pytest.mark.parametrize("launcher", ["slurm", "submitit", "ray_cluster"])
def test_launcher_configs_compose_with_the_plugins_schema(launcher: str) -> None:
    """Each launcher file extends the plugin's own (typed) config: a key the plugin does not
    know, or a value of the wrong type, fails here, not on the cluster."""
    needs({"ray_cluster": "hydra_ray_launcher"}.get(launcher, "hydra_submitit_launcher"))
    from hydra import compose, initialize_config_dir
    from omegaconf import OmegaConf

    with initialize_config_dir(str(REPO_ROOT / "conf"), version_base=None):
        cfg = compose("config", [f"hydra/launcher={launcher}", "jobs=3",
                                 "hydra.launcher.mem_gb=16" if launcher != "ray_cluster" else
                                 "hydra.launcher.ray.remote.num_cpus=4"],
                      return_hydra_config=True)
    hl = OmegaConf.to_container(cfg.hydra.launcher, resolve=False)
    if launcher == "ray_cluster":
        assert hl["_target_"].endswith("RayLauncher") and hl["ray"]["remote"]["num_cpus"] == 4
        return
    assert hl["_target_"].endswith("SlurmLauncher" if launcher == "slurm" else "LocalLauncher")
    assert cfg.hydra.launcher.cpus_per_task == 3 and cfg.hydra.launcher.mem_gb == 16
    assert cfg.hydra.launcher.timeout_min == 120
    if launcher == "slurm":
        assert "partition" in hl and cfg.hydra.launcher.array_parallelism == 64


def test_search_group_composes_a_typed_objective_and_an_optuna_space() -> None:
    needs("hydra_optuna_sweeper")
    from hydra import compose, initialize_config_dir

    from blindspot.cli import SearchConfig
    from blindspot.typed_config import ConfigError

    with initialize_config_dir(str(REPO_ROOT / "conf"), version_base=None):
        cfg = compose("config", ["+search=lstm"], return_hydra_config=True)
    assert SearchConfig.from_mapping(cfg.search).objective == "lstm.val.ade_m"
    assert cfg.hydra.sweeper.storage == "sqlite:///optuna.db"  # a study that outlives the search
    assert cfg.hydra.sweeper._target_.endswith("OptunaSweeper")
    assert cfg.hydra.sweeper.direction == "minimize" and cfg.hydra.sweeper.sampler.seed == 0
    assert set(cfg.hydra.sweeper.params) == {"model.hidden_size", "model.num_layers",
                                             "model.head_hidden", "train.lr", "train.batch_size"}
    with pytest.raises(ConfigError, match="search.objektive"):
        SearchConfig.from_mapping({"objektive": "x"})
