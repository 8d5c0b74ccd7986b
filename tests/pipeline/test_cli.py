"""`python -m blindspot ...` and `python stages/<name>.py` (main_stage), run as real processes."""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

import pytest

from blindspot import config
from tests.pipeline.toy_repo import blindspot, clean_env, make_toy_repo, run, logged_runs


@pytest.fixture()
def toy(tmp_path: Path) -> Path:
    root = make_toy_repo(tmp_path / "repo")
    config.write_params(root)
    return root


def test_stage_with_overrides_from_a_subdirectory(toy: Path) -> None:
    proc = blindspot(["toy", "train.lr=0.5", "model.hidden_size=4"], toy / "stages")
    # the overrides differ from params.yaml: the outs go to the run's own folder (under the
    # repo root), never over the pipeline's
    assert not (toy / "out" / "toy.json").exists()
    (written,) = toy.glob("outputs/*/*/out/toy.json")
    assert json.loads(written.read_text()) == {"hidden_size": 4, "lr": 0.5, "score": 2.0}
    assert "dvc exp run -S 'model.hidden_size=4' -S 'train.lr=0.5'" in proc.stderr
    (r,) = logged_runs(toy)
    assert r.data.tags["blindspot.out_root"] == str(written.parents[1])
    assert r.info.status == "FINISHED" and r.info.run_name == "toy"
    assert r.data.params["train.lr"] == "0.5" and r.data.params["model.hidden_size"] == "4"
    assert r.data.tags["toy.cwd"] == str(toy.resolve())
    assert r.data.tags["hydra.overrides"] == "train.lr=0.5 model.hidden_size=4"
    assert r.data.metrics["score"] == pytest.approx(4.0)  # last step: epoch 2 of 2


def test_unknown_stage_lists_the_stages(toy: Path) -> None:
    proc = blindspot(["tarin", "x=1"], toy, check=False)
    assert proc.returncode == 2
    assert "unknown stage 'tarin'" in proc.stderr and "Stages: toy" in proc.stderr
    proc = blindspot(["stages"], toy)
    assert proc.stdout.split() == ["toy"]


def test_cfg_job_prints_config_and_logs_nothing(toy: Path) -> None:
    proc = blindspot(["toy", "--cfg", "job", "train.lr=0.25"], toy)
    assert "lr: 0.25" in proc.stdout
    assert logged_runs(toy) == []


def test_params_and_check_params_commands(toy: Path) -> None:
    assert "up to date" in blindspot(["check-params"], toy).stdout
    (toy / "conf" / "model" / "small.yaml").write_text("hidden_size: 24\nlayers: [1, 2]\n")
    proc = blindspot(["check-params"], toy, check=False)
    assert proc.returncode == 1
    assert "model.hidden_size: params.yaml has 16, conf/ gives 24" in proc.stderr
    assert "Fix: run `python -m blindspot params`" in proc.stderr
    assert blindspot(["params", "x=1"], toy, check=False).returncode == 2
    blindspot(["params"], toy)
    assert config.load_params(toy).model.hidden_size == 24
    blindspot(["check-params"], toy)
    cfg = toy / "conf" / "config.yaml"
    cfg.write_text(cfg.read_text().replace("model: small", "model: huge"))
    for command in ("params", "check-params"):
        proc = blindspot([command], toy, check=False)
        assert proc.returncode == 1 and "Could not find 'model/huge'" in proc.stderr
        assert "Traceback" not in proc.stderr


def test_main_stage_reads_params_yaml_and_refuses_arguments(toy: Path) -> None:
    py = sys.executable
    proc = run([py, "stages/toy.py", "train.lr=3"], toy, check=False)
    assert proc.returncode == 2 and "python -m blindspot toy train.lr=3" in proc.stderr
    # Stale params.yaml under `dvc repro` / by hand: refuse, with the fix.
    (toy / "conf" / "train" / "base.yaml").write_text("lr: 0.3\nepochs: 2\n")
    proc = run([py, "stages/toy.py"], toy, check=False)
    assert proc.returncode == 1 and "python -m blindspot params" in proc.stderr
    assert logged_runs(toy) == []
    # Inside `dvc exp run` DVC composed params.yaml itself: it is used as is.
    text = (toy / "params.yaml").read_text().replace("lr: 0.1", "lr: 0.05")
    (toy / "params.yaml").write_text(text)
    run([py, str(toy / "stages" / "toy.py")], toy / "conf", env=clean_env(DVC_EXP_NAME="e1"))
    (r,) = logged_runs(toy)
    assert r.data.params["train.lr"] == "0.05" and r.data.tags["dvc.exp_name"] == "e1"
    assert r.info.run_name == "toy@e1"
    assert json.loads((toy / "out" / "toy.json").read_text())["lr"] == 0.05


def _sweep_runs(toy: Path) -> tuple[object, list]:
    found = logged_runs(toy)
    parents = [r for r in found if r.data.tags.get("blindspot.sweep") == "true"]
    assert len(parents) == 1, [r.info.run_name for r in found]
    children = [r for r in found if r is not parents[0]]
    assert {r.data.tags.get("mlflow.parentRunId") for r in children} == {parents[0].info.run_id}
    return parents[0], sorted(children, key=lambda r: int(r.data.tags["hydra.job_num"]))


def test_multirun_parent_with_one_child_per_job(toy: Path) -> None:
    blindspot(["toy", "-m", "model.hidden_size=8,16"], toy)
    parent, children = _sweep_runs(toy)
    assert parent.info.status == "FINISHED"
    assert re.fullmatch(r"toy-sweep-\d{8}-\d{6}", parent.info.run_name), parent.info.run_name
    assert parent.data.tags["hydra.overrides"] == "model.hidden_size=8,16"
    # what the sweep varies is a param (and a tag) of its parent
    assert parent.data.params == {"model.hidden_size": "8,16"}
    assert parent.data.tags["blindspot.overrides"] == "model.hidden_size=8,16"
    assert [c.data.params["model.hidden_size"] for c in children] == ["8", "16"]
    assert [c.info.run_name for c in children] == ["toy#0", "toy#1"]
    assert {c.info.status for c in children} == {"FINISHED"}
    assert [c.data.metrics["score"] for c in children] == pytest.approx([1.6, 3.2])


def test_joblib_multirun_reuses_workers_without_leaking_runs(toy: Path) -> None:
    blindspot(["toy", "-m", "hydra/launcher=parallel", "model.hidden_size=1,2,3"], toy)
    parent, children = _sweep_runs(toy)
    assert parent.info.status == "FINISHED"
    assert [c.data.params["model.hidden_size"] for c in children] == ["1", "2", "3"]
    assert {c.info.status for c in children} == {"FINISHED"}
    pids = [c.data.tags["toy.pid"] for c in children]
    assert len(set(pids)) < len(pids) == 3  # 2 loky workers, 3 jobs: a worker was reused ...
    # ... and each job still logged into its own run only: one score series per child.
    for c, h in zip(children, [1, 2, 3], strict=True):
        assert c.data.metrics["score"] == pytest.approx(0.1 * h * 2)


def test_failed_sweep_job_fails_parent_not_running(toy: Path) -> None:
    proc = blindspot(["toy", "-m", "toy.fail=false,true"], toy, check=False)
    assert proc.returncode != 0 and "toy stage asked to fail" in proc.stderr
    parent, children = _sweep_runs(toy)
    assert [c.info.status for c in children] == ["FINISHED", "FAILED"]
    assert parent.info.status == "FAILED"


@pytest.mark.parametrize("override, new", [("tracking.enabled=false", "runs.enabled=false"),
                                           ("+benchmark.n_walks=3", "walks.n_walks=3"),
                                           ("benchmark=scene_walks", "walks=scene_walks")])
def test_a_renamed_config_key_names_its_new_name(override, new, capsys) -> None:
    from blindspot.cli import main

    assert main(["walks", override]) == 2
    err = capsys.readouterr().err
    assert f"write {new} instead" in err and "Traceback" not in err


def test_a_params_file_with_a_renamed_key_names_it(tmp_path) -> None:
    from blindspot import config as bconfig

    (tmp_path / "params.yaml").write_text("tracking:\n  enabled: true\n")
    with pytest.raises(bconfig.RenamedKey, match="'tracking' was renamed 'runs'"):
        bconfig.load_params(tmp_path)


def test_a_single_run_never_writes_over_the_pipeline(toy: Path) -> None:
    # only output-neutral keys changed (tracking, progress bars): the pipeline's own outs
    blindspot(["toy", "runs.enabled=false", "progress=true"], toy)
    assert json.loads((toy / "out" / "toy.json").read_text())["lr"] == 0.1
    # an override with the run folder pointed at the repository root: refused, with the fix
    proc = blindspot(["toy", "train.lr=0.3", "hydra.run.dir=.", "runs.enabled=false"], toy,
                     check=False)
    assert proc.returncode == 1 and "dvc exp run -S 'train.lr=0.3'" in proc.stderr
    assert json.loads((toy / "out" / "toy.json").read_text())["lr"] == 0.1


def _with_upstream(root: Path) -> Path:
    """The toy repo with a stage 'make' whose out data/made.json is a dep of 'toy' (not made)."""
    dvc = (root / "dvc.yaml").read_text().replace(
        "      - stages/toy.py\n", "      - stages/toy.py\n      - data/made.json\n", 1)
    dvc += ("  make:\n    cmd: python stages/make.py\n    outs:\n      - data/made.json\n")
    (root / "dvc.yaml").write_text(dvc)
    return root


def test_missing_inputs_names_the_file_the_stage_making_it_and_the_command(tmp_path: Path
                                                                            ) -> None:
    from blindspot.stage import MissingInput, missing_inputs

    root = _with_upstream(make_toy_repo(tmp_path / "repo", store=False))
    with pytest.raises(MissingInput, match=r"(?s)stage 'toy' cannot run: 1 of its inputs .*"
                       r"data/made.json: made by stage 'make' \(python -m blindspot make\).*"
                       r"`dvc repro toy`"):
        missing_inputs(root, "toy")
    (root / "data").mkdir()
    (root / "data" / "made.json").write_text("{}")
    missing_inputs(root, "toy")                       # all there: passes
    missing_inputs(root, "not_in_dvc_yaml")           # a stage dvc.yaml does not know: passes


def test_a_stage_run_before_its_inputs_exist_says_what_makes_them_without_traceback(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture) -> None:
    # t3_c24: `python -m blindspot driving_track` in a fresh clone ended in a traceback
    from blindspot.cli import main

    root = _with_upstream(make_toy_repo(tmp_path / "repo", store=False))
    config.write_params(root)
    monkeypatch.chdir(root)
    assert main(["toy", "train.lr=0.5"]) == 1
    err = capsys.readouterr().err
    assert "data/made.json: made by stage 'make'" in err and "dvc repro toy" in err
    assert "Traceback" not in err and not (root / "out").exists()
    proc = run([sys.executable, "stages/toy.py"], root, check=False)     # the DVC entry point
    assert proc.returncode == 1 and "Traceback" not in proc.stderr
    assert "data/made.json: made by stage 'make'" in proc.stderr
