"""A sweep never writes over the pipeline's DVC-tracked outputs (issue 13).

The real ``train`` stage, swept on the parallel (joblib) launcher over two hidden sizes, in a copy
of this repository whose windows are a small synthetic data set: the pipeline's outputs (the
windows, ``data/train/*`` and ``reports/metrics/train.json``) keep their bytes; each job writes its
own model and metrics under its own job directory; MLflow holds one child run per job, nested
under the sweep's parent, with the swept value as a param and the validation metric; the sweep's
directory holds ``sweep_summary.csv``.
"""

from __future__ import annotations

import csv
import hashlib
import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import REPO_ROOT
from tests.pipeline.toy_repo import _template_db, blindspot, logged_runs

PIPELINE_OUTS = ("data/train/model.pt", "data/train/history.csv", "reports/metrics/train.json")


def copy_code(dest: Path) -> Path:
    """The repository's committed and new (not ignored) files, without data/ and reports/."""
    import shutil

    files = subprocess.run(["git", "ls-files", "-co", "--exclude-standard", "-z"], cwd=REPO_ROOT,
                           capture_output=True, text=True, check=True).stdout.split("\0")
    for rel in filter(None, files):
        src = REPO_ROOT / rel
        if src.is_file() and rel.split("/")[0] in {"conf", "src", "stages"} | {"dvc.yaml",
                                                                              "params.yaml"}:
            (dest / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dest / rel)
    shutil.copy(_template_db(), dest / "mlflow.db")
    return dest


def synthetic_windows(root: Path, window: int) -> None:
    """Constant-velocity walks with noise, as train/val/test windows (what `windows` writes):
    one walk of ``window + 28`` points per 8 windows (stride 3, the first 8 of its 10 windows),
    so the split holds the next 20 points (the validation rollout) of each walk's first window."""
    from blindspot.traj.windows import make_windows

    rng = np.random.default_rng(0)
    for split, n in (("train", 256), ("val", 64), ("test", 32)):
        walks = n // 8
        v = rng.uniform(-1.5, 1.5, (walks, 1, 2)) * 0.1  # m per 0.1 s frame
        t = np.arange(window + 28)[None, :, None]
        xy = rng.uniform(-5, 5, (walks, 1, 2)) + v * t + rng.normal(0, 0.02, (walks, t.size, 2))
        ws = make_windows(xy, window, stride=3)             # 28 / 3 -> 10 windows per walk
        ws.subset(np.arange(len(ws)) % 10 < 8).save(root / "data" / "windows" / f"{split}.parquet")


def digest(root: Path) -> dict[str, str]:
    return {p.relative_to(root).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for top in ("data", "reports") for p in sorted((root / top).rglob("*")) if p.is_file()}


@pytest.fixture
def repo(tmp_path: Path) -> Path:
    root = copy_code(tmp_path / "repo")
    synthetic_windows(root, window=50)
    # Stand-ins for what the last `dvc repro` left: bytes no training run can produce.
    for i, rel in enumerate(PIPELINE_OUTS):
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        (root / rel).write_bytes(f"pipeline output {i}\n".encode())
    return root


def test_parallel_sweep_leaves_pipeline_outputs_byte_identical(repo: Path) -> None:
    before = digest(repo)
    blindspot(["train", "-m", "hydra/launcher=parallel", "profile=tiny", "train.epochs=1",
               "progress=false", "jobs=1", "model.hidden_size=8,16",
               "hydra.sweep.dir=multirun/sweep"], repo, timeout=300)
    assert digest(repo) == before, "a sweep job wrote over the pipeline's outputs"

    sweep = repo / "multirun" / "sweep"
    for job, hidden in ((0, 8), (1, 16)):
        metrics = json.loads((sweep / str(job) / "reports/metrics/train.json").read_text())
        assert metrics["n_windows"] == {"train": 256, "val": 64, "test": 32}
        assert 0 < metrics["lstm"]["val"]["rmse_m"] < 1.0
        assert (sweep / str(job) / "data/train/model.pt").stat().st_size > 1000
    found = logged_runs(repo)
    parents = [r for r in found if r.data.tags.get("blindspot.sweep") == "true"]
    assert len(parents) == 1 and parents[0].info.status == "FINISHED"
    children = sorted((r for r in found if r.data.tags.get("mlflow.parentRunId")
                       == parents[0].info.run_id), key=lambda r: r.data.tags["hydra.job_num"])
    assert [r.data.params["model.hidden_size"] for r in children] == ["8", "16"]
    assert all(r.info.status == "FINISHED" and "lstm.val.rmse_m" in r.data.metrics
               for r in children)
    assert [r.data.tags["blindspot.out_root"] for r in children] == [
        str((sweep / str(j)).resolve()) for j in (0, 1)]

    with open(sweep / "sweep_summary.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [row["run_id"] for row in rows] == [r.info.run_id for r in children]
    assert [float(row["lstm.val.rmse_m"]) for row in rows] == pytest.approx(
        [r.data.metrics["lstm.val.rmse_m"] for r in children])
