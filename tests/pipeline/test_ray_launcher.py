"""A two-job sweep through Hydra's Ray launcher on a Ray head this test starts (127.0.0.1) and
stops: each job runs as a Ray task in a Ray worker process and logs its own MLflow run, with its
params and metrics, nested under the sweep's parent run (issue 13)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from tests.conftest import REPO_ROOT
from tests.pipeline.scaleout import ray_head
from tests.pipeline.test_launchers import sweep_runs
from tests.pipeline.toy_repo import blindspot, clean_env, make_toy_repo

pytestmark = pytest.mark.slow  # a Ray head takes ~10 s to start on 2 cores, each worker ~5 s


def test_two_job_sweep_through_the_ray_launcher(tmp_path: Path) -> None:
    pytest.importorskip("hydra_plugins.hydra_ray_launcher", reason="make setup-cluster")
    root = make_toy_repo(tmp_path / "repo")
    shutil.copy(REPO_ROOT / "conf" / "hydra" / "launcher" / "ray_cluster.yaml",
                root / "conf" / "hydra" / "launcher")
    with ray_head(num_cpus=2) as address:
        blindspot(["toy", "-m", "hydra/launcher=ray_cluster", "hydra.launcher.ray.remote.num_cpus=1",
                   "hydra.sweep.dir=multirun/ray", "model.hidden_size=8,32"], root,
                  env=clean_env(RAY_ADDRESS=address, RAY_USAGE_STATS_ENABLED="0"), timeout=300)
    parent, children = sweep_runs(root)
    assert parent.info.status == "FINISHED"
    assert [r.data.params["model.hidden_size"] for r in children] == ["8", "32"]
    assert [r.data.metrics["score"] for r in children] == pytest.approx([1.6, 6.4])
    assert all(r.info.status == "FINISHED" for r in children)
    # Ray workers ran the jobs: processes other than the launching one
    assert parent.data.tags["blindspot.pid"] not in {r.data.tags["toy.pid"] for r in children}
    for job in (0, 1):
        assert (root / f"multirun/ray/{job}/out/toy.json").is_file()
