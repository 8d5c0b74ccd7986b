"""Runs that say what changed (issue 46), without DVC or a browser: a child's params are its
stage's keys, a sweep is named by its kind, the runs page's view collects the columns to show,
README's link opens it."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from blindspot import runs
from blindspot.runs.changes import (
    overrides_against_conf,
    overrides_tag,
    parse_overrides,
    stage_param_keys,
    stage_params,
    sweep_run_name,
)
from blindspot.runs.view import VIEW_TAG, add_to_view, runs_page_url
from tests.pipeline.toy_repo import REPO, make_toy_repo

VALUES = {"model": {"hidden_size": 16, "layers": [1, 2]}, "train": {"lr": 0.1, "epochs": 2},
          "seed": 0, "runs": {"enabled": True, "uri": None}}


def test_a_child_logs_its_stage_keys_only(tmp_path: Path) -> None:
    root = make_toy_repo(tmp_path / "repo")
    keys = stage_param_keys(root, "toy")
    assert keys == ("model.hidden_size", "train.lr", "train.epochs")
    assert stage_param_keys(root, "nope") is None
    assert stage_params(VALUES, keys) == {"model.hidden_size": 16, "train.lr": 0.1,
                                          "train.epochs": 2}
    assert stage_params(VALUES, ("model",)) == {"model.hidden_size": 16, "model.layers": [1, 2]}
    assert len(stage_params(VALUES, None)) == 7  # a stage dvc.yaml does not know: everything
    with runs.stage_run("toy", VALUES, repo_root=root) as tracker:
        pass
    run = runs.get_client(runs.settings_from_cfg(VALUES, root)).get_run(tracker.run_id)
    assert set(run.data.params) == {"model.hidden_size", "train.lr", "train.epochs"}


def test_the_real_train_stage_logs_tens_of_keys_not_hundreds() -> None:
    from blindspot.config import load_params
    from omegaconf import OmegaConf

    values = OmegaConf.to_container(load_params(REPO), resolve=True)
    every = stage_params(values, None)
    train = stage_params(values, stage_param_keys(REPO, "train"))
    assert len(every) > 400 and 5 < len(train) < 100, (len(every), len(train))


def test_overrides_against_conf_are_what_an_experiment_changed(tmp_path: Path) -> None:
    root = make_toy_repo(tmp_path / "repo")
    from blindspot.config import compose
    from omegaconf import OmegaConf

    values = OmegaConf.to_container(compose(config_dir=root / "conf"), resolve=True)
    assert overrides_against_conf(values, root / "conf") == {}
    values["train"]["lr"] = 0.01
    changed = overrides_against_conf(values, root / "conf")
    assert changed == {"train.lr": 0.01} and overrides_tag(changed) == "train.lr=0.01"


def test_sweeps_are_named_by_kind_and_study() -> None:
    assert parse_overrides(["model.hidden_size=32,64", "+search=lstm", "~seed"]) == {
        "model.hidden_size": "32,64", "search": "lstm", "seed": ""}
    optuna = "hydra_plugins.hydra_optuna_sweeper.optuna_sweeper.OptunaSweeper"
    assert sweep_run_name("train", optuna, None, "lstm") == "train-optuna-lstm"
    submitit = "hydra_plugins.hydra_submitit_launcher.submitit_launcher.LocalLauncher"
    basic = "hydra._internal.core_plugins.basic_sweeper.BasicSweeper"
    assert sweep_run_name("train", basic, submitit, None, now=0).startswith("train-submitit-19")
    assert sweep_run_name("train", basic, "hydra_plugins.hydra_joblib_launcher.x", None
                          ).startswith("train-sweep-")


def test_the_view_collects_metric_then_param_columns(tmp_path: Path) -> None:
    settings = runs.settings_from_cfg(VALUES, make_toy_repo(tmp_path / "repo"))
    client = runs.get_client(settings)
    exp = runs.ensure_experiment(settings)
    add_to_view(client, exp, metrics=["headline.ade_m"], params=["train.lr"])
    add_to_view(client, exp, metrics=["headline.fde_m", "headline.ade_m"], params=["seed"])
    state = json.loads(client.get_experiment(exp).tags[VIEW_TAG])
    assert state["selectedColumns"] == ["metrics.`headline.ade_m`", "metrics.`headline.fde_m`",
                                        "params.`train.lr`", "params.`seed`"]


def test_readme_links_the_view() -> None:
    assert runs_page_url("http://127.0.0.1:5000", "1") in (REPO / "README.md").read_text()


@pytest.mark.parametrize("name", ["headline"])
def test_the_parent_gets_the_headline_stage_numbers(name: str) -> None:
    from blindspot.config import load_params

    headline = load_params(REPO).runs.headline
    assert list(headline) == [name] and list(headline[name]) == ["*"]
