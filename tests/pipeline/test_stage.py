"""blindspot.stage and cli.run_stage: the runner hands a stage its declared files and a live
metric logger, and logs the StageResult it returns (the one door to MLflow)."""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest
from mlflow.tracking import MlflowClient
from omegaconf import OmegaConf

from blindspot import cli
from blindspot.stage import DeclaredFiles, StageContext, StageResult, UndeclaredPath, declared_files
from tests.pipeline.toy_repo import make_toy_repo

DVC_YAML = """
stages:
  make:
    cmd: python stages/make.py
    deps:
      - stages/make.py
      - data/in/truth.parquet
    outs:
      - data/make/points.parquet
      - data/make/dir
      - reports/figures/fig.png:
          cache: false
    metrics:
      - reports/metrics/make.json:
          cache: false
    plots:
      - data/make/history.csv:
          x: epoch
  other:
    cmd: python stages/other.py
    outs: [data/other/points.parquet]
"""


@pytest.fixture()
def repo(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    for key in ("MLFLOW_TRACKING_URI", "BLINDSPOT_MLFLOW_PARENT_RUN_ID", "DVC_EXP_NAME"):
        monkeypatch.delenv(key, raising=False)
    root = make_toy_repo(tmp_path / "repo", dvc_yaml=False)
    (root / "dvc.yaml").write_text(textwrap.dedent(DVC_YAML))
    monkeypatch.chdir(root)  # run_stage changes the cwd: restored after the test
    return root


def test_declared_files_reads_outs_metrics_and_plots(repo: Path) -> None:
    files = declared_files(repo, "make")
    assert files.deps == ("stages/make.py", "data/in/truth.parquet")
    assert files.outs == ("data/make/points.parquet", "data/make/dir", "reports/figures/fig.png",
                          "reports/metrics/make.json", "data/make/history.csv")
    assert declared_files(repo, "nope") == DeclaredFiles("nope", (), ())


def test_context_resolves_names_and_refuses_undeclared_or_ambiguous() -> None:
    ctx = StageContext(DeclaredFiles("s", ("data/a/x.parquet", "data/b/x.parquet"),
                                     ("data/s/out.json", "reports/s/out.json", "data/s/y.csv")))
    assert ctx.out("y.csv") == Path("data/s/y.csv")
    assert ctx.out("data/s/out.json") == Path("data/s/out.json")
    assert ctx.dep("a/x.parquet") == Path("data/a/x.parquet")
    with pytest.raises(UndeclaredPath, match=r"stage 's'.*declares 2 matching out 'out.json'"):
        ctx.out("out.json")
    with pytest.raises(UndeclaredPath, match=r"declares 2 matching dep 'x.parquet'"):
        ctx.dep("x.parquet")
    with pytest.raises(UndeclaredPath, match=r"declares no out 'z.csv'.*data/s/y.csv"):
        ctx.out("z.csv")
    with pytest.raises(UndeclaredPath, match="declares no out 'csv'"):
        ctx.out("csv")  # a trailing part of the path means whole path components


def test_check_outs_names_what_was_not_written(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    ctx = StageContext(DeclaredFiles("s", (), ("a.json", "b.json", "c.json")))
    Path("a.json").write_text("{}")
    ctx.out("a.json"), ctx.out("b.json")
    with pytest.raises(UndeclaredPath, match=r"never asked for c.json; asked for but missing b.json"):
        ctx.check_outs()
    Path("b.json").write_text("{}")
    ctx.out("c.json")
    Path("c.json").write_text("{}")
    ctx.check_outs()


def test_stage_result_wants_sequences_of_paths() -> None:
    with pytest.raises(TypeError, match="wrap it in a list"):
        StageResult(artifacts="reports/fig.png")


def _make_stage(fail_to_write: bool = False):
    def run(cfg, ctx):
        for epoch in range(3):
            ctx.log_step({"loss": 1.0 / (epoch + 1)}, epoch)
        outs = [ctx.out(n) for n in ("points.parquet", "fig.png", "make.json", "history.csv")]
        (ctx.out("dir") / "inner").mkdir(parents=True, exist_ok=True)
        for p in outs[1 if fail_to_write else 0:]:
            p.parent.mkdir(parents=True, exist_ok=True)
            p.write_text("x")
        return StageResult(metrics={"val": {"rmse_m": 0.25}, "n": 3}, artifacts=[outs[1]],
                           model_files=[outs[0]] if not fail_to_write else [],
                           tags={"made.by": "test"})
    return run


CFG = {"runs": {"enabled": True, "uri": None, "experiment": "blindspot"}, "x": 1}


def test_run_stage_logs_the_result_and_live_steps(repo: Path) -> None:
    result = cli.run_stage(_make_stage(), "make", OmegaConf.create(CFG), repo, check_outs=True)
    assert result.tags == {"made.by": "test"}
    client = MlflowClient(tracking_uri=f"sqlite:///{repo / 'mlflow.db'}")
    exp = client.get_experiment_by_name("blindspot")
    (run,) = client.search_runs([exp.experiment_id])
    assert run.info.status == "FINISHED" and run.data.tags["made.by"] == "test"
    assert run.data.metrics["val.rmse_m"] == 0.25 and run.data.metrics["n"] == 3
    assert [m.step for m in client.get_metric_history(run.info.run_id, "loss")] == [0, 1, 2]
    names = {a.path for a in client.list_artifacts(run.info.run_id)}
    assert {"fig.png", "model", "config"} <= names
    assert [a.path for a in client.list_artifacts(run.info.run_id, "model")] == ["model/points.parquet"]


def test_run_stage_fails_the_run_when_an_out_is_not_written(repo: Path) -> None:
    with pytest.raises(UndeclaredPath, match="missing data/make/points.parquet"):
        cli.run_stage(_make_stage(fail_to_write=True), "make", OmegaConf.create(CFG), repo,
                      check_outs=True)
    # outside DVC (python -m blindspot, overrides may change what is written) it is not checked
    cli.run_stage(_make_stage(fail_to_write=True), "make", OmegaConf.create(CFG), repo)


def test_run_stage_wants_a_stage_result(repo: Path) -> None:
    cfg = OmegaConf.create({**CFG, "runs": {"enabled": False}})
    with pytest.raises(TypeError, match=r"stage 'other'.*returned NoneType"):
        cli.run_stage(lambda cfg, ctx: None, "other", cfg, repo)


def _per_recording_stage(fail_at: str | None):
    """Writes one parquet and one figure per recording, then a summary, like real_tracking;
    raises at recording ``fail_at``."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import pandas as pd

    from blindspot import io

    def run(cfg, ctx):
        for name in ("a", "b"):
            if name == fail_at:
                raise ValueError(f"recording {name}: unreadable")
            io.write_parquet(ctx.out("points.parquet").with_name(f"{name}.parquet"),
                             pd.DataFrame({"x": [1.0]}))
            fig = plt.figure()
            io.save_figure(fig, ctx.out("fig.png"))
            plt.close(fig)
        with io.atomic_dir(ctx.out("dir")) as folder:
            io.write_text(folder / "inner.txt", "whole")
        io.write_json(ctx.out("make.json"), {"ok": True})
        return StageResult()
    return run


def test_a_stage_that_fails_at_its_second_recording_leaves_nothing(repo: Path) -> None:
    """issue 45: all of a stage's outputs appear or none do; before, the first recording's new
    files (and figure) stayed beside the others' old ones."""
    cfg = OmegaConf.create({**CFG, "tracking": {"enabled": False}})
    with pytest.raises(ValueError, match="recording b"):
        cli.run_stage(_per_recording_stage("b"), "make", cfg, repo)
    made = [p for p in (repo / "data").rglob("*")] + list((repo / "reports").rglob("*"))
    assert [p for p in made if p.is_file()] == []              # no output, no temporary
    cli.run_stage(_per_recording_stage(None), "make", cfg, repo)
    before = {p: p.read_bytes() for p in (repo / "data").rglob("*") if p.is_file()}
    assert (repo / "data/make/a.parquet") in before and (repo / "data/make/dir/inner.txt") in before
    assert (repo / "reports/metrics/make.json").is_file()
    with pytest.raises(ValueError, match="recording a"):        # a later failed run: unchanged
        cli.run_stage(_per_recording_stage("a"), "make", cfg, repo)
    assert {p: p.read_bytes() for p in (repo / "data").rglob("*") if p.is_file()} == before
