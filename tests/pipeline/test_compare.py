"""Comparing experiments the way DVC users do (issue 46), on the toy repository, for real.

Two `dvc exp run -S` experiments: `dvc exp show` at 120 columns shows their headline numbers
(the one DVC metrics file), not `…`; `dvc metrics diff` fits 120 columns. A single run with an
override (`python -m blindspot toy train.lr=...`) leaves every tracked output byte-identical and
`dvc status` clean. A persistent output that is cached comes back with `dvc checkout` (status
clean). And static checks of the real dvc.yaml: one metrics file, the detailed JSONs outs.
"""

from __future__ import annotations

import hashlib
import json
import re
import shutil
import subprocess
from pathlib import Path

import pytest
import yaml

from tests.pipeline.toy_repo import REPO, VENV_BIN, blindspot, clean_env, make_toy_repo, run

pytestmark = pytest.mark.pipeline

DVC = VENV_BIN / "dvc"
if not DVC.exists() or shutil.which("git") is None:  # pragma: no cover - environment guard
    pytest.skip(f"needs git and {DVC}", allow_module_level=True)

# A second stage with a persistent, cached output (like train's checkpoints): `dvc checkout`
# must bring it back, so `dvc status` is clean on a complete cache.
CKPT_STAGE = """
  ckpt:
    cmd: mkdir -p ckpt && echo epoch-1 > ckpt/last.txt
    outs:
      - ckpt:
          persist: true
"""


def dvc(*args: str, repo: Path, env: dict[str, str] | None = None, **kw: object):  # noqa: ANN201
    return run([str(DVC), *args], repo, env=env or clean_env(), **kw)  # type: ignore[arg-type]


def _digests(root: Path, paths: list[str]) -> dict[str, str]:
    out = {}
    for rel in paths:
        p = root / rel
        files = sorted(f for f in p.rglob("*") if f.is_file()) if p.is_dir() else [p]
        for f in files:
            out[str(f.relative_to(root))] = hashlib.sha256(f.read_bytes()).hexdigest()
    return out


@pytest.fixture(scope="module")
def repo(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = make_toy_repo(tmp_path_factory.mktemp("compare") / "repo")
    with open(root / "dvc.yaml", "a") as fh:
        fh.write(CKPT_STAGE)
    for cmd in (["git", "init", "-q", "-b", "main"],
                ["git", "config", "user.email", "test@example.com"],
                ["git", "config", "user.name", "test"]):
        run(cmd, root)
    dvc("init", "-q", repo=root)
    dvc("config", "hydra.enabled", "true", repo=root)
    blindspot(["params"], root)
    dvc("repro", repo=root)
    run(["git", "add", "-A"], root)
    run(["git", "commit", "-qm", "toy pipeline"], root)
    return root


def test_exp_show_at_120_columns_shows_both_experiments_headline_numbers(repo: Path) -> None:
    expected = {}
    # Named (-n): DVC's random names vary in length, and the Experiment column with them. DVC
    # collapses columns from the right to fit: the deps' hash and the first param always stay,
    # so at 120 columns the first few metrics of the one metrics file show, in its key order.
    for name, override, (lr, hidden) in (("lr35", "train.lr=0.35", (0.35, 16)),
                                         ("h21", "model.hidden_size=21", (0.1, 21))):
        proc = dvc("exp", "run", "-n", name, "-S", override, repo=repo)
        assert re.search(rf"Ran experiment\(s\): {name}\b", proc.stdout + proc.stderr)
        score = lr * hidden
        expected[name] = (f"{score:.5g}", f"{score * 2:.5g}")  # final: 2 epochs
    env = clean_env(COLUMNS="120", LINES="50")
    shown = dvc("exp", "show", "--no-pager", repo=repo, env=env).stdout
    lines = shown.splitlines()
    assert max(len(line) for line in lines) <= 120, shown
    header = next(line for line in lines if "Experiment" in line)
    assert "score" in header and "final" in header, shown
    for name, numbers in expected.items():
        row = next((line for line in lines if f"[{name}]" in line), None)
        assert row is not None, f"{name} not in\n{shown}"
        cells = row.split()
        assert all(n in cells for n in numbers), f"{name}: {numbers} not in {row!r}\n{shown}"
    # `dvc metrics diff`: one row per headline key, well inside 120 columns
    diff = dvc("metrics", "diff", "--all", repo=repo, env=env).stdout
    assert "final" in diff and max(map(len, diff.splitlines())) <= 120, diff


def _back_to_baseline(repo: Path) -> None:
    """The committed baseline (an experiment's results were applied to the workspace)."""
    run(["git", "checkout", "--", "."], repo)
    dvc("checkout", "-q", repo=repo)


def test_a_single_run_with_an_override_leaves_tracked_outputs_alone(repo: Path) -> None:
    _back_to_baseline(repo)
    tracked = ["out/toy.json", "out/headline.json", "ckpt", "dvc.lock", "params.yaml"]
    before = _digests(repo, tracked)
    proc = blindspot(["toy", "train.lr=0.9"], repo)
    assert _digests(repo, tracked) == before  # byte-identical
    assert "dvc exp run -S 'train.lr=0.9'" in proc.stderr
    (own,) = repo.glob("outputs/*/*/out/toy.json")
    assert json.loads(own.read_text())["lr"] == 0.9
    assert "up to date" in dvc("status", repo=repo).stdout
    # (without overrides it writes the pipeline's outputs: test_cli.py)


def test_checkout_on_a_complete_cache_gives_a_clean_status(repo: Path) -> None:
    _back_to_baseline(repo)
    shutil.rmtree(repo / "ckpt")  # a fresh clone: git has the rest, the cache has this
    assert "deleted" in dvc("status", repo=repo).stdout
    dvc("checkout", repo=repo)
    status = dvc("status", repo=repo).stdout
    assert "up to date" in status, status
    assert (repo / "ckpt" / "last.txt").read_text() == "epoch-1\n"


# --------------------------------------------------------------------------- the real dvc.yaml


def _real_stages() -> dict:
    return yaml.safe_load((REPO / "dvc.yaml").read_text())["stages"]


def _paths(entries) -> list[str]:  # noqa: ANN001
    return [next(iter(e)) if isinstance(e, dict) else e for e in entries or ()]


def test_the_pipeline_declares_one_metrics_file_and_keeps_the_detailed_ones_as_outs() -> None:
    stages = _real_stages()
    metrics = [p for s in stages.values() for p in _paths(s.get("metrics"))]
    assert metrics == ["reports/metrics/headline.json"]
    outs = {p for s in stages.values() for p in _paths(s.get("outs"))}
    committed = {f"reports/metrics/{p.name}" for p in (REPO / "reports" / "metrics").glob("*.json")}
    assert committed - {"reports/metrics/headline.json"} <= outs
    # every persistent output is cached, so `dvc checkout` restores it (no "deleted" in status),
    # or kept by git (README.md, whose generated block the report stage rewrites)
    tracked = set(subprocess.run(["git", "ls-files"], cwd=REPO, capture_output=True, text=True,
                                 check=True).stdout.split())
    for name, spec in stages.items():
        for entry in spec.get("outs") or ():
            if isinstance(entry, dict):
                path, opts = next(iter(entry.items()))
                opts = opts or {}
                assert not (opts.get("persist") and opts.get("cache") is False
                            and path not in tracked), (name, entry)


def test_headline_from_the_committed_metrics() -> None:
    from blindspot.report.headline import HEADLINE, SOURCES, headline_metrics, read_sources

    found = headline_metrics(read_sources(
        {n: REPO / "reports" / "metrics" / f"{n}.json" for n in SOURCES}))
    assert 15 <= len(found) <= len(HEADLINE) and list(found) == [k for k in HEADLINE if k in found]
    assert all(isinstance(v, float) and len(f"{v:.5g}") <= 8 for v in found.values()), found
    assert found["paper_err_m"] == pytest.approx(json.loads(
        (REPO / "reports/metrics/evaluate.json").read_text())["lstm"]["path_error_mean_m"], 1e-3)
    assert headline_metrics({}) == {}  # nothing run yet: an empty file, not an error
