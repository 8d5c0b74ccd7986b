"""The whole pipeline, for real: `dvc repro` of the tiny profile in a temporary git repository.

Every stage runs (simulation, detection, localisation, the real recordings, the radar-measured
path data set, windows, training, interpolation, prediction, evaluation, figures, tables, the
report page) and writes exactly the files dvc.yaml declares; a second `dvc repro` with nothing changed reruns nothing but the params check; each
computing stage lands one FINISHED MLflow run in the copy's SQLite store.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import time
from pathlib import Path

import pytest

from blindspot.stage import read_dvc_stages
from tests.conftest import REPO_ROOT, SHARED
from tests.pipeline.toy_repo import VENV_BIN, clean_env, run, logged_runs

pytestmark = pytest.mark.pipeline

DVC = VENV_BIN / "dvc"
# What the exp-run test asks for, and the stages it must (and only they) rerun; also what
# benchmarks/bench_tiny_repro.py times.
EXP_RUN = ["exp", "run", "-S", "train.lr=0.003", "interpolate"]
EXP_RERUNS = {"train", "interpolate"}


def copy_worktree(dest: Path) -> Path:
    """The repository's tracked and untracked-but-not-ignored files (what a commit would hold)."""
    files = subprocess.run(["git", "ls-files", "-co", "--exclude-standard", "-z"], cwd=REPO_ROOT,
                           capture_output=True, text=True, check=True).stdout.split("\0")
    for rel in filter(None, files):
        src = REPO_ROOT / rel
        if src.is_file() and not rel.startswith(("data/", "reports/", "mlflow.db")):
            (dest / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dest / rel)
    return dest


def make_tiny_repo(dest: Path, env: dict[str, str]) -> Path:
    """A git repository at ``dest``: this working tree (no data, no dvc.lock) on the tiny profile,
    params.yaml composed, all committed."""
    root = copy_worktree(dest)
    (root / "dvc.lock").unlink(missing_ok=True)  # the paper profile's: what runs gets locked
    cfg = root / "conf" / "config.yaml"
    cfg.write_text(cfg.read_text().replace("  - profile: paper", "  - profile: tiny"))
    for cmd in (["git", "init", "-q", "-b", "main"], ["git", "config", "user.email", "t@example.com"],
                ["git", "config", "user.name", "t"]):
        run(cmd, root, env=env)
    run([str(VENV_BIN / "python"), "-m", "blindspot", "params"], root, env=env)
    run(["git", "add", "-A"], root, env=env)
    run(["git", "commit", "-qm", "tiny"], root, env=env)
    return root


@pytest.fixture(scope="module")
def tiny_repo(tmp_path_factory: pytest.TempPathFactory) -> Path:
    if not (SHARED / "data" / "radar").is_dir():
        pytest.skip(f"shared recordings not found at {SHARED}")
    return make_tiny_repo(tmp_path_factory.mktemp("repro") / "repo",
                          clean_env(BLINDSPOT_SHARED=str(SHARED)))


def test_dvc_repro_tiny_profile_end_to_end(tiny_repo: Path) -> None:
    env = clean_env(BLINDSPOT_SHARED=str(SHARED))
    t0 = time.monotonic()
    proc = run([str(DVC), "repro"], tiny_repo, env=env, timeout=1800)
    first = time.monotonic() - t0
    reports = tiny_repo / "reports"
    for fig in ("fig04", "fig06", "fig07", "fig08", "fig09", "fig10"):
        png = reports / "figures" / f"{fig}.png"
        assert png.stat().st_size > 20_000, f"{png} missing or empty"
    for table in ("table1", "table2"):
        text = (reports / "tables" / f"{table}.md").read_text()
        assert "| parameter | paper | ours |" in text, text[:300]
    evaluate = json.loads((reports / "metrics" / "evaluate.json").read_text())
    for method in ("lstm", "constant_velocity", "kalman"):
        m = evaluate[method]
        assert 0 < m["path_error_mean_m"] < 5 and 0 < m["ade_m"] < 10, (method, m)
        assert m["path_error_mean_m"] <= m["ade_m"] + 1e-9  # nearest point is never farther
    train = json.loads((reports / "metrics" / "train.json").read_text())
    assert train["n_windows"] == {"train": 1000, "val": 300, "test": 100}
    assert (reports / "README.md").read_text().count("0.09") >= 1
    # What the stages wrote is exactly what dvc.yaml declares (DVC ignores undeclared files).
    declared = [o for files in read_dvc_stages(tiny_repo).values() for o in files.outs]
    written = sorted(p.relative_to(tiny_repo).as_posix() for top in ("data", "reports")
                     for p in (tiny_repo / top).rglob("*") if p.is_file() and p.name != ".gitignore")
    undeclared = [w for w in written if not any(w == o or w.startswith(o + "/") for o in declared)]
    assert not undeclared, f"files no dvc.yaml stage declares: {undeclared}"
    assert [o for o in declared if not (tiny_repo / o).exists()] == []
    finished = [r for r in logged_runs(tiny_repo) if r.info.status == "FINISHED"]
    stages = {r.data.tags.get("blindspot.stage") for r in finished}
    assert {"simulate", "detect", "localise", "paths", "train", "evaluate"} <= stages, stages
    assert all(r.info.status != "RUNNING" for r in logged_runs(tiny_repo))

    t0 = time.monotonic()
    again = run([str(DVC), "repro"], tiny_repo, env=env, timeout=300)
    second = time.monotonic() - t0
    ran = [line for line in again.stdout.splitlines() if line.startswith("Running stage")]
    assert ran == ["Running stage 'check_params':"], again.stdout
    assert second < first / 3, (first, second)
    print(f"dvc repro (tiny): {first:.0f} s; nothing changed: {second:.1f} s\n{proc.stdout[-2000:]}")


def test_dvc_exp_run_override_reruns_only_what_depends_on_it(tiny_repo: Path) -> None:
    """`dvc exp run -S train.lr=... interpolate` composes conf/ + the override (Hydra) and
    reruns training and the stage after it on the way to the target, never the radar stages
    above them; the run logs the new value to MLflow.

    The target keeps the claim and drops the cost: DVC still checks every stage it depends on
    (simulate, detect, localise through the points; paths, windows through the model), none of
    whose params hold train.lr, while the other stages a new model reruns (calibration, predict,
    evaluate, benchmark, safety, the figures and tables, the report page) would only repeat
    what the first test shows, that a changed dependency reruns its stage
    (benchmarks/bench_tiny_repro.py times this exp run)."""
    env = clean_env(BLINDSPOT_SHARED=str(SHARED))
    if not (tiny_repo / "dvc.lock").exists():  # this test run alone
        run([str(DVC), "repro"], tiny_repo, env=env, timeout=1800)
    run(["git", "add", "-A"], tiny_repo, env=env)
    run(["git", "commit", "-qm", "baseline", "--allow-empty"], tiny_repo, env=env)
    proc = run([str(DVC), *EXP_RUN], tiny_repo, env=env, timeout=1200)
    ran = {line.split("'")[1] for line in proc.stdout.splitlines() if line.startswith("Running stage")}
    assert ran == EXP_RERUNS, proc.stdout
    assert not ran & {"simulate", "detect", "localise", "paths", "windows", "recordings"}, ran
    train_runs = [r for r in logged_runs(tiny_repo) if r.data.tags.get("blindspot.stage") == "train"]
    assert train_runs[-1].data.params["train.lr"] == "0.003"
