"""A shared tracking store: PostgreSQL 15 + an MLflow server with proxied artifacts, started on
127.0.0.1 by the project's own `blindspot.runs.server` and stopped after (issue 13).

A three-job parallel sweep logs to it over HTTP; MLflow's REST API then shows every run, param,
metric and artifact; a sweep job SIGKILLed mid-run (no handler can run) ends KILLED once
`python -m blindspot cleanup` (or the next run) finds its process gone.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import urllib.parse
import urllib.request
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.pipeline.toy_repo import blindspot, clean_env, make_toy_repo

pytestmark = pytest.mark.slow  # PostgreSQL + MLflow's migrations: ~30 s idle, minutes when busy


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    pytest.importorskip("psycopg2", reason="make setup-cluster")
    from blindspot.runs import server as srv

    try:
        srv.pg_bin_dir()
    except FileNotFoundError as exc:
        pytest.skip(str(exc))
    # Under root PostgreSQL runs as `postgres`, which cannot enter pytest's private tmp folders.
    folder = Path(tempfile.mkdtemp(prefix="blindspot-mlflow-server-"))
    folder.chmod(0o755)
    try:
        info = srv.start(folder, timeout_s=300)
        yield info.tracking_uri
    finally:
        srv.stop(folder)
        shutil.rmtree(folder, ignore_errors=True)


def rest(uri: str, endpoint: str, body: dict | None = None, **query: str) -> dict:
    """GET (``query``) or POST (``body``) ``<uri>/api/2.0/mlflow/<endpoint>``; the JSON answer."""
    url = f"{uri}/api/2.0/mlflow/{endpoint}"
    if query:
        url += "?" + urllib.parse.urlencode(query)
    data = None if body is None else json.dumps(body).encode()
    req = urllib.request.Request(url, data=data, headers={"Content-Type": "application/json"})
    with urllib.request.urlopen(req, timeout=60) as resp:
        return json.loads(resp.read())


def search(uri: str) -> list[dict]:
    exp = rest(uri, "experiments/get-by-name", experiment_name="blindspot")["experiment"]
    return rest(uri, "runs/search", {"experiment_ids": [exp["experiment_id"]],
                                     "max_results": 1000}).get("runs", [])


def tags(run: dict) -> dict[str, str]:
    return {t["key"]: t["value"] for t in run["data"].get("tags", [])}


def test_three_job_sweep_lands_on_the_postgres_server(server: str, tmp_path: Path) -> None:
    root = make_toy_repo(tmp_path / "repo", store=False)
    env = clean_env(MLFLOW_TRACKING_URI=server)
    blindspot(["toy", "-m", "hydra/launcher=parallel", "model.hidden_size=8,16,32"], root,
              env=env, timeout=600)
    assert not (root / "mlflow.db").exists()  # nothing fell back to the local SQLite file
    found = search(server)
    parents = [r for r in found if tags(r).get("blindspot.sweep") == "true"]
    assert len(parents) == 1 and parents[0]["info"]["status"] == "FINISHED"
    parent_id = parents[0]["info"]["run_id"]
    children = [r for r in found if tags(r).get("mlflow.parentRunId") == parent_id]
    by_size = {p["value"]: r for r in children for p in r["data"]["params"]
               if p["key"] == "model.hidden_size"}
    assert sorted(by_size, key=int) == ["8", "16", "32"]
    for size, run in by_size.items():
        assert run["info"]["status"] == "FINISHED"
        metrics = {m["key"]: m["value"] for m in run["data"]["metrics"]}
        assert metrics["score"] == pytest.approx(2 * 0.1 * int(size))  # last epoch: 2 x lr x h
        history = rest(server, "metrics/get-history", run_id=run["info"]["run_id"],
                       metric_key="score")["metrics"]
        assert sorted(m["step"] for m in history) == [0, 1]
        files = rest(server, "artifacts/list", run_id=run["info"]["run_id"])["files"]
        sizes = {f["path"]: int(f.get("file_size", 0)) for f in files}
        assert sizes.get("toy.json", 0) > 0, files  # uploaded through the server's proxy
        assert run["info"]["artifact_uri"].startswith("mlflow-artifacts:")


def test_sigkilled_sweep_job_ends_killed(server: str, tmp_path: Path) -> None:
    root = make_toy_repo(tmp_path / "repo", store=False)
    env = clean_env(MLFLOW_TRACKING_URI=server)
    proc = subprocess.Popen([sys.executable, "-m", "blindspot", "toy", "-m", "toy.sleep_s=120",
                             "model.hidden_size=4"], cwd=root, env=env, start_new_session=True,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 300
        while not (root / "out" / "started").exists():
            assert proc.poll() is None and time.monotonic() < deadline, "the job never started"
            time.sleep(0.5)
    finally:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(30)
    pid = str(proc.pid)
    running = [r for r in search(server) if tags(r).get("blindspot.pid") == pid]
    assert {r["info"]["status"] for r in running} == {"RUNNING"}  # the sweep parent and its job
    blindspot(["cleanup"], root, env=env, timeout=300)
    ended = {r["info"]["run_id"]: r for r in search(server) if tags(r).get("blindspot.pid") == pid}
    assert len(ended) == 2 and {r["info"]["status"] for r in ended.values()} == {"KILLED"}
    assert all("closed KILLED" in tags(r)["blindspot.closed_stale"] for r in ended.values())


def test_ray_sweep_jobs_log_to_the_server(server: str, tmp_path: Path) -> None:
    """The issue's set-up: sweep jobs running as Ray tasks (Ray workers do not inherit the
    launching shell's environment) log to the shared server, each under the sweep's parent."""
    pytest.importorskip("hydra_plugins.hydra_ray_launcher", reason="make setup-cluster")
    from tests.conftest import REPO_ROOT
    from tests.pipeline.scaleout import ray_head

    root = make_toy_repo(tmp_path / "repo", store=False)
    shutil.copy(REPO_ROOT / "conf" / "hydra" / "launcher" / "ray_cluster.yaml",
                root / "conf" / "hydra" / "launcher")
    with ray_head(num_cpus=2) as address:
        blindspot(["toy", "-m", "hydra/launcher=ray_cluster", "hydra.launcher.ray.remote.num_cpus=1",
                   "hydra.sweep.dir=multirun/ray", "model.hidden_size=8,32"], root,
                  env=clean_env(MLFLOW_TRACKING_URI=server, RAY_ADDRESS=address,
                                RAY_USAGE_STATS_ENABLED="0"), timeout=300)
    assert not (root / "mlflow.db").exists()  # nothing fell back to the local SQLite file
    found = search(server)
    parents = [r for r in found if tags(r).get("blindspot.sweep") == "true"]
    parent = max(parents, key=lambda r: r["info"]["start_time"])  # this test's sweep: the latest
    children = [r for r in found if tags(r).get("mlflow.parentRunId") == parent["info"]["run_id"]]
    sizes = sorted(int(p["value"]) for r in children for p in r["data"]["params"]
                   if p["key"] == "model.hidden_size")
    assert sizes == [8, 32] and all(r["info"]["status"] == "FINISHED" for r in children)
    assert all(r["info"]["artifact_uri"].startswith("mlflow-artifacts:") for r in children)
