"""DVC + Hydra + MLflow together, for real, in a temporary git repository with a toy stage.

Covers: `dvc repro`; the params check under `dvc repro`; `dvc exp run -S` (DVC composes conf/
into params.yaml); `dvc exp run --queue` + `dvc queue start -j 2`, whose runs execute in
temporary copies under <repo>/.dvc/tmp/exps/ and must still land in the ORIGINAL repo's store.
"""

from __future__ import annotations

import json
import re
import shutil
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from blindspot import config
from tests.pipeline.toy_repo import VENV_BIN, blindspot, clean_env, make_toy_repo, run, logged_runs

pytestmark = pytest.mark.pipeline

DVC = VENV_BIN / "dvc"
if not DVC.exists() or shutil.which("git") is None:  # pragma: no cover - environment guard
    pytest.skip(f"needs git and {DVC}", allow_module_level=True)


def dvc(*args: str, repo: Path, **kw: object):  # noqa: ANN201 - CompletedProcess
    return run([str(DVC), *args], repo, **kw)  # type: ignore[arg-type]


@pytest.fixture(scope="module")
def repo(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    root = make_toy_repo(tmp_path_factory.mktemp("dvc") / "repo")
    with open(root / "conf" / "runs" / "local.yaml", "a") as fh:  # below `headline:`
        fh.write("  toy: [score]\n")
    env = clean_env()
    for cmd in (["git", "init", "-q", "-b", "main"],
                ["git", "config", "user.email", "test@example.com"],
                ["git", "config", "user.name", "test"]):
        run(cmd, root, env=env)
    dvc("init", "-q", repo=root)
    dvc("config", "hydra.enabled", "true", repo=root)
    blindspot(["params"], root)
    run(["git", "add", "-A"], root)
    run(["git", "commit", "-qm", "toy pipeline"], root)
    yield root
    dvc("queue", "stop", repo=root, check=False, timeout=60)


def _commit(root: Path, message: str) -> None:
    run(["git", "add", "-A"], root)
    run(["git", "commit", "-qm", message, "--allow-empty"], root)


def pipeline_and_stages(new: list) -> tuple[list, list]:
    """(pipeline parent runs, stage runs) among ``new``."""
    parents = [r for r in new if r.data.tags.get("blindspot.pipeline") == "true"]
    return parents, [r for r in new if r not in parents]


def test_dvc_repro_runs_the_stage_and_logs_it(repo: Path) -> None:
    before = len(logged_runs(repo))
    dvc("repro", repo=repo)
    parents, new = pipeline_and_stages(logged_runs(repo)[before:])
    assert len(new) == 1 and len(parents) == 1
    r, parent = new[0], parents[0]
    assert r.info.status == "FINISHED"
    # One parent run per `dvc repro`: the stages are its children, its headline metrics theirs.
    assert r.data.tags["mlflow.parentRunId"] == parent.info.run_id
    assert parent.info.status == "FINISHED" and parent.info.run_name == "dvc repro"
    assert parent.data.tags["mlflow.source.git.commit"] == r.data.tags["mlflow.source.git.commit"]
    # runs.headline has toy: [score]; the child's last value (epoch 2: 2 x 0.1 x 16)
    assert parent.data.metrics == {"toy.score": pytest.approx(r.data.metrics["score"])}
    assert r.data.metrics["score"] == pytest.approx(3.2)
    assert r.data.tags["dvc.stage"] == "toy" and "dvc.exp_name" not in r.data.tags
    assert r.data.params["train.lr"] == "0.1" and r.data.params["model.hidden_size"] == "16"
    # a stage logs the keys its dvc.yaml entry lists, not the whole config; the parent of a
    # `dvc repro` of the defaults changed nothing
    assert set(r.data.params) == {"model.hidden_size", "train.lr", "train.epochs"}
    assert parent.data.params == {} and parent.data.tags["blindspot.overrides"] == ""
    assert json.loads((repo / "out" / "toy.json").read_text())["score"] == pytest.approx(1.6)
    assert "score" in dvc("metrics", "show", repo=repo).stdout
    _commit(repo, "repro")
    dvc("repro", repo=repo)  # nothing changed: nothing runs, nothing logged
    assert len(logged_runs(repo)) == before + 2


def test_dvc_repro_refuses_params_stale_against_conf(repo: Path) -> None:
    dvc("repro", repo=repo)     # up to date, whether or not the test above ran first
    _commit(repo, "repro")
    small = repo / "conf" / "model" / "small.yaml"
    original = small.read_text()
    small.write_text(original.replace("hidden_size: 16", "hidden_size: 20"))
    try:
        # DVC alone sees nothing changed (it tracks params.yaml, not conf/) ...
        assert "toy" not in dvc("status", repo=repo).stdout
        # ... and the stage itself refuses to run on the stale params.yaml.
        proc = dvc("repro", "-f", repo=repo, check=False)
        assert proc.returncode != 0
        assert "model.hidden_size: params.yaml has 16, conf/ gives 20" in proc.stdout + proc.stderr
        assert "python -m blindspot params" in proc.stdout + proc.stderr
    finally:
        small.write_text(original)


def test_dvc_exp_run_set_param_composes_conf_into_params(repo: Path) -> None:
    before = len(logged_runs(repo))
    proc = dvc("exp", "run", "-S", "train.lr=0.01", repo=repo)
    name = re.search(r"Ran experiment\(s\): (\S+)", proc.stdout + proc.stderr).group(1)
    params = config.load_params(repo)
    assert params.train.lr == 0.01 and params.model.hidden_size == 16
    parents, new = pipeline_and_stages(logged_runs(repo)[before:])
    assert len(new) == 1 and len(parents) == 1
    r = new[0]
    assert r.data.params["train.lr"] == "0.01" and r.data.tags["dvc.exp_name"] == name
    assert parents[0].data.tags["dvc.exp_name"] == name and parents[0].info.run_name == f"exp {name}"
    assert parents[0].data.tags["mlflow.source.git.commit"] == r.data.tags["dvc.baseline_rev"]
    assert parents[0].data.metrics == {"toy.score": pytest.approx(0.32)}
    # what the experiment changed (its -S value) is a param and a tag of its parent
    assert parents[0].data.params == {"train.lr": "0.01"}
    assert parents[0].data.tags["blindspot.overrides"] == "train.lr=0.01"
    assert r.data.tags["mlflow.source.git.commit"] == r.data.tags["dvc.baseline_rev"]
    assert json.loads((repo / "out" / "toy.json").read_text())["lr"] == 0.01
    run(["git", "checkout", "--", "."], repo)  # back to the committed baseline (tmp repo)


def _wait_for_queue(repo: Path, n_runs: int, timeout_s: float = 300) -> str:
    """Wait until ``n_runs`` runs ended in the store (cheap to poll), then until DVC's queue
    has collected every experiment (each `dvc queue status` costs a DVC start-up)."""
    deadline = time.time() + timeout_s
    while sum(r.info.status != "RUNNING" for r in logged_runs(repo)) < n_runs:
        assert time.time() < deadline, f"only {len(logged_runs(repo))} runs after {timeout_s} s"
        time.sleep(0.5)
    while True:
        status = dvc("queue", "status", repo=repo).stdout
        if not re.search(r"\b(Queued|Running)\b", status):
            return status
        assert time.time() < deadline, f"queue still busy after {timeout_s} s:\n{status}"
        time.sleep(1.0)


def test_dvc_queue_runs_land_in_the_original_store(repo: Path) -> None:
    before = len(logged_runs(repo))
    proc = dvc("exp", "run", "--queue", "-S", "model.hidden_size=32,64", repo=repo)
    queued = re.findall(r"Queued experiment '([^']+)'", proc.stdout + proc.stderr)
    assert len(queued) == 2
    dvc("queue", "start", "-j", "2", repo=repo)
    status = _wait_for_queue(repo, before + 4)  # two experiments: a parent and a stage run each
    for name in queued:
        assert re.search(rf"{re.escape(name)}\s+.*Success", status), status

    parents, new = pipeline_and_stages(logged_runs(repo)[before:])
    by_name = {r.data.tags["dvc.exp_name"]: r for r in new}
    parent_of = {r.data.tags["dvc.exp_name"]: r.info.run_id for r in parents}
    assert sorted(parent_of) == sorted(queued)
    assert all(r.data.tags["mlflow.parentRunId"] == parent_of[n] for n, r in by_name.items())
    assert sorted(by_name) == sorted(queued)
    assert sorted(r.data.params["model.hidden_size"] for r in new) == ["32", "64"]
    assert {r.info.status for r in new} == {"FINISHED"}
    for r in new:
        # They ran in DVC's temporary copies, yet logged into <repo>/mlflow.db.
        workdir = Path(r.data.tags["blindspot.workdir"])
        assert workdir.parent == repo.resolve() / ".dvc" / "tmp" / "exps", workdir
        assert workdir.name.startswith("tmp")
        assert r.data.tags["blindspot.repo"] == str(repo.resolve())
        art = Path(r.info.artifact_uri.removeprefix("file://"))
        assert art.is_relative_to(repo.resolve() / "mlartifacts") and any(art.rglob("toy.json"))
    shown = dvc("exp", "show", "--json", repo=repo).stdout
    assert all(name in shown for name in queued)
