"""A tiny blindspot-shaped repository for the pipeline tests (conf/, stages/toy.py, dvc.yaml).

Only test helpers live here; the repository under test is created in a pytest tmp_path, so the
real conf/ groups (written elsewhere) are not needed. The tracking and launcher configs are
copied from the real conf/ so the shipped files are the ones exercised.
"""

from __future__ import annotations

import atexit
import os
import shutil
import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
VENV_BIN = Path(sys.executable).parent

TOY_STAGE = '''
"""Toy stage: score = lr * hidden_size, logged per epoch; optional sleep for signal tests."""
import os
import time
from pathlib import Path

from blindspot import cli, io
from blindspot.stage import StageResult


def run(cfg, ctx):
    score = float(cfg.train.lr) * int(cfg.model.hidden_size)
    for epoch in range(int(cfg.train.epochs)):
        ctx.log_step({"score": score * (epoch + 1), "nested": {"half": score / 2}}, epoch)
    out = io.write_json(
        ctx.out("toy.json"),
        {"score": score, "lr": cfg.train.lr, "hidden_size": cfg.model.hidden_size},
    )
    if any(o.endswith("headline.json") for o in ctx.files.outs):  # the DVC metrics file
        io.write_json(ctx.out("headline.json"),
                      {"score": score, "final": score * int(cfg.train.epochs)})
    if cfg.toy.sleep_s:
        with io.atomic_open("out/partial.txt") as fh:
            fh.write("half")
            Path("out/started").write_text(str(os.getpid()))
            time.sleep(float(cfg.toy.sleep_s))
    if cfg.toy.fail:
        raise RuntimeError("toy stage asked to fail")
    return StageResult(artifacts=[out], tags={"toy.pid": os.getpid(), "toy.cwd": os.getcwd()})


if __name__ == "__main__":
    cli.main_stage(run, "toy")
'''

CONFIG = """
defaults:
  - model: small
  - train: base
  - runs: local
  - _self_

seed: 0
progress: false
toy:
  sleep_s: 0
  fail: false
"""

DVC_YAML = """
stages:
  toy:
    cmd: python stages/toy.py
    deps:
      - stages/toy.py
    params:
      - model.hidden_size
      - train.lr
      - train.epochs
    outs:
      - out/toy.json:
          cache: false
    metrics:
      - out/headline.json:
          cache: false
"""


_TEMPLATE_DB: Path | None = None


def _template_db() -> Path:
    """An empty MLflow SQLite store (schema only), created once per test session.

    Creating MLflow's schema (alembic migrations) costs seconds; copying the file costs
    nothing. Only the schema and MLflow's "Default" experiment are in it: the "blindspot"
    experiment is still created by blindspot.runs in each repo.
    """
    global _TEMPLATE_DB
    if _TEMPLATE_DB is None:
        from mlflow.tracking import MlflowClient

        folder = Path(tempfile.mkdtemp(prefix="blindspot-mlflow-template-"))
        atexit.register(shutil.rmtree, folder, True)
        db = folder / "mlflow.db"
        MlflowClient(tracking_uri=f"sqlite:///{db}").search_experiments(max_results=1)
        _TEMPLATE_DB = db
    return _TEMPLATE_DB


def make_toy_repo(root: Path, *, dvc_yaml: bool = True, store: bool = True) -> Path:
    """Write conf/, stages/toy.py and (optionally) dvc.yaml under ``root``; returns ``root``.

    ``store``: start with an empty MLflow store copied from a session template (fast);
    False leaves the store to be created by the code under test.
    """
    (root / "conf" / "model").mkdir(parents=True)
    (root / "conf" / "train").mkdir()
    (root / "conf" / "runs").mkdir()
    (root / "conf" / "hydra" / "launcher").mkdir(parents=True)
    (root / "stages").mkdir()
    (root / "conf" / "config.yaml").write_text(textwrap.dedent(CONFIG).lstrip())
    (root / "conf" / "model" / "small.yaml").write_text("hidden_size: 16\nlayers: [1, 2]\n")
    (root / "conf" / "train" / "base.yaml").write_text("lr: 0.1\nepochs: 2\n")
    shutil.copy(REPO / "conf" / "runs" / "local.yaml", root / "conf" / "runs")
    shutil.copy(REPO / "conf" / "hydra" / "launcher" / "parallel.yaml",
                root / "conf" / "hydra" / "launcher")
    (root / "stages" / "toy.py").write_text(TOY_STAGE.lstrip())
    if store:
        shutil.copy(_template_db(), root / "mlflow.db")
    if dvc_yaml:
        (root / "dvc.yaml").write_text(textwrap.dedent(DVC_YAML).lstrip())
    (root / ".gitignore").write_text("/mlflow.db\n/mlflow.db.lock\n/mlartifacts/\n/outputs/\n"
                                     "/multirun/\n/out/started\n")
    return root


def clean_env(**extra: str) -> dict[str, str]:
    """Environment for subprocesses: venv first on PATH, no inherited tracking/DVC state."""
    env = {k: v for k, v in os.environ.items()
           if not k.startswith(("MLFLOW_", "DVC_", "BLINDSPOT_MLFLOW"))}
    env["PATH"] = f"{VENV_BIN}{os.pathsep}{env.get('PATH', '')}"
    env["HYDRA_FULL_ERROR"] = "1"
    env["DVC_NO_ANALYTICS"] = "1"
    env.update(extra)
    return env


def run(cmd: list[str], cwd: Path, *, timeout: float = 300, check: bool = True,
        env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    """Run ``cmd`` in ``cwd``; on failure the assertion shows stdout and stderr."""
    proc = subprocess.run(cmd, cwd=cwd, env=env or clean_env(), capture_output=True, text=True,
                          timeout=timeout)
    if check and proc.returncode != 0:
        raise AssertionError(
            f"{' '.join(cmd)} exited {proc.returncode}\n--- stdout\n{proc.stdout}\n"
            f"--- stderr\n{proc.stderr}"
        )
    return proc


def blindspot(args: list[str], cwd: Path, **kw: object) -> subprocess.CompletedProcess[str]:
    """``python -m blindspot ARGS`` with the venv's python."""
    return run([sys.executable, "-m", "blindspot", *args], cwd, **kw)  # type: ignore[arg-type]


def logged_runs(root: Path, experiment: str = "blindspot") -> list:
    """All MLflow runs of ``experiment`` in ``root``'s SQLite store, oldest first."""
    from mlflow.tracking import MlflowClient

    client = MlflowClient(tracking_uri=f"sqlite:///{root / 'mlflow.db'}")
    exp = client.get_experiment_by_name(experiment)
    if exp is None:
        return []
    found = client.search_runs([exp.experiment_id], max_results=1000)
    return sorted(found, key=lambda r: r.info.start_time)
