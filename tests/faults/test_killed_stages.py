"""Every DVC stage, killed (SIGKILL or SIGTERM) at a seeded point, leaves nothing that looks done.

One tiny-profile repository is prepared for the module: `dvc repro` of the stages a test needs,
traced (:mod:`tests.faults.harness`), its outputs fingerprinted. Then, per stage of dvc.yaml (a
new stage is covered without editing this file): the stage's command runs with a kill armed and
afterwards

(a) every output is absent or byte-identical to the undisturbed run (a directory out whole or
    absent; a persisted out, train's resume checkpoints, readable files only); no temporary
    file is left that DVC would count as part of an output; no worker of
    the stage outlives it;
(b) `dvc status` shows the stage changed, unless every output was already complete;
(c) after the next start (the rerun, or `python -m blindspot cleanup` when DVC reruns nothing),
    the killed stage's MLflow run is KILLED or FAILED, never RUNNING (a SIGKILLed run is closed
    by blindspot.runs.stale);
(d) `dvc repro -s --no-run-cache <stage>` computes the undisturbed bytes again and, with that
    next start, no temporary file is left.

Budget: the default suite kills one representative heavy stage (DEFAULT) at a seeded fault
point, one signal each (alternating along dvc.yaml); every other stage is killed
the same way with -m slow (`pytest -m slow tests/faults`), where each stage is also killed with
the other signal after a seeded delay.
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import pytest
import yaml

from tests.conftest import REPO_ROOT, SHARED
from tests.faults.harness import (
    Kill,
    Snapshot,
    declared_outs,
    draw_point_kill,
    draw_timed_kill,
    read_trace,
    run_killed,
    stage_specs,
    temp_debris,
    unreadable,
)
from tests.pipeline.test_repro import DVC, make_tiny_repo
from tests.pipeline.toy_repo import clean_env, run, logged_runs

pytestmark = pytest.mark.pipeline

SPECS = stage_specs(REPO_ROOT)
# The default suite's share: recordings (a directory out filled by a heavy stage; SIGKILL at a
# fault point inside it; 46 s on the idle 2-core machine). train (per-epoch MLflow metrics, a
# model file, a checkpoint folder, outputs holding a wall time; SIGTERM) took 78 s and moved to
# -m slow with every other stage to keep the default suite near 15 minutes; SIGTERM ending a run
# KILLED and a SIGKILLed run closed on the next start stay in the default suite
# (tests/pipeline/test_runs.py, tests/faults/test_fault_points.py). All of -m slow
# tests/faults: 29 min.
DEFAULT = ("recordings",)
SIGNALS = (signal.SIGKILL, signal.SIGTERM)


def _default_signal(stage: str) -> signal.Signals:
    """One signal per stage in the default suite, alternating along dvc.yaml."""
    return SIGNALS[list(SPECS).index(stage) % 2]


@dataclass
class Prepared:
    """The tiny repository, what it has reproduced and the undisturbed outputs."""

    root: Path
    env: dict[str, str]
    trace_dir: Path
    snapshot: Snapshot = field(default_factory=lambda: Snapshot({}))
    seconds: dict[str, float] = field(default_factory=dict)  # a stage's rerun, DVC included

    def dvc(self, *args: str, check: bool = True, extra: dict[str, str] | None = None,
            timeout: float = 900) -> subprocess.CompletedProcess[str]:
        return run([str(DVC), *args], self.root, env={**self.env, **(extra or {})},
                   check=check, timeout=timeout)

    def ensure(self, stage: str) -> None:
        """`dvc repro <stage>` (and what it needs), traced, then fingerprint the new outputs."""
        if stage in self.snapshot.files:
            return
        self.dvc("repro", stage, extra={"BLINDSPOT_FAULT_TRACE": str(self.trace_dir)})
        lock = self.root / "dvc.lock"
        done = set(yaml.safe_load(lock.read_text())["stages"]) if lock.exists() else set()
        done.add(stage)  # a stage without outs (check_params) is not locked
        fresh = {s: SPECS[s] for s in done if s not in self.snapshot.files}
        self.snapshot.files.update(Snapshot.take(self.root, fresh).files)


@pytest.fixture(scope="module")
def prepared(tmp_path_factory: pytest.TempPathFactory) -> Prepared:
    if not (SHARED / "data" / "radar").is_dir():
        pytest.skip(f"shared recordings not found at {SHARED}")
    base = tmp_path_factory.mktemp("faults")
    env = clean_env(BLINDSPOT_SHARED=str(SHARED), PYTHONPATH=str(REPO_ROOT / "src"))
    return Prepared(make_tiny_repo(base / "repo", env), env, base / "traces")


def check_killed_stage(prepared: Prepared, stage: str, kill: Kill) -> None:
    """Kill ``stage`` as ``kill`` says and check (a)-(d) of the module docstring."""
    root, spec = prepared.root, SPECS[stage]
    outs = declared_outs(spec)
    before = {r.info.run_id for r in logged_runs(root)}
    killed = run_killed(root, spec, kill, prepared.env)
    why = f"{stage} killed by {kill}; exit {killed.returncode}\n{killed.stderr[-3000:]}"
    if kill.k is not None:  # a point kill always fires: the stage may not have finished
        expected = {-signal.SIGKILL} if kill.signal == signal.SIGKILL else {143, -signal.SIGTERM}
        assert killed.returncode in expected, why

    # (a) nothing looks complete unless it is; a persisted out (train's resume checkpoints)
    # keeps the state of the interrupted run by design, so there every file must only be whole
    # (readable), not the undisturbed run's bytes
    kept = declared_outs(spec, persist=True)
    fresh = [o for o in outs if o not in kept]
    assert prepared.snapshot.differences(root, stage, fresh, absent_ok=True) == [], why
    assert unreadable(root, kept) == [], why
    assert killed.survivors == [], f"{why}\nworkers left running: {killed.survivors}"
    debris = temp_debris(root, outs)
    if debris:  # only a SIGKILL may leave them, and DVC must not see them
        assert kill.signal == signal.SIGKILL, f"{why}\ntemporary files left: {debris}"
        rel = sorted(p.relative_to(root).as_posix() for p in debris)
        ignored = prepared.dvc("check-ignore", *rel, check=False).stdout.split()
        assert rel == sorted(ignored), f"{why}\nnot .dvcignored: {rel}"

    # (b) DVC sees the stage changed, unless the kill came after every output was complete
    absent = prepared.snapshot.differences(root, stage, outs, absent_ok=False)
    complete = not absent
    status = json.loads(prepared.dvc("status", stage, "--json").stdout or "{}")
    assert stage in status or complete, f"{why}\ndvc status: {status}"

    # (d) a rerun (computed again: not restored from DVC's run cache) gives the undisturbed
    # bytes back and sweeps the debris away; when DVC reruns nothing (the outputs were complete)
    # the housekeeping command does what the stage's next start would
    t0 = time.monotonic()
    rerun = prepared.dvc("repro", "-s", "--no-run-cache", stage)
    if f"Running stage '{stage}'" in rerun.stdout:
        prepared.seconds[stage] = time.monotonic() - t0
    else:
        run([sys.executable, "-m", "blindspot", "cleanup"], root, env=prepared.env)
    assert prepared.snapshot.differences(root, stage, outs, absent_ok=False) == [], why
    assert temp_debris(root, outs) == [], why

    # (c) the killed run ended KILLED or FAILED (a SIGKILLed one closed by the next start); a
    # delay that outlived the stage may find it FINISHED, with every output complete
    assert [r.info.run_id for r in logged_runs(root) if r.info.status == "RUNNING"] == [], why
    statuses = []
    for r in logged_runs(root):
        if r.info.run_id in before or r.data.tags.get("blindspot.pid") != str(killed.pid):
            continue
        if kill.k is not None or r.info.status != "FINISHED":
            assert r.info.status in {"KILLED", "FAILED"}, (why, r.info.run_id, r.info.status)
        else:
            assert complete, (why, "run FINISHED but outputs incomplete")
        if kill.signal == signal.SIGKILL and r.info.status == "KILLED":
            assert "closed KILLED by process" in r.data.tags.get("blindspot.closed_stale", ""), why
        statuses.append(r.info.status)
    left = "complete" if complete else f"{len(prepared.snapshot.files[stage]) - len(absent)} of " \
        f"{len(prepared.snapshot.files[stage])} files, the rest absent"
    print(f"[faults] {stage}: {kill}, exit {killed.returncode}; outputs {left}; "
          f"debris {len(debris)}; run {'/'.join(statuses) or 'none'}; rerun identical")


def _point_or_timed(prepared: Prepared, stage: str, sig: signal.Signals, salt: str = "") -> Kill:
    points = read_trace(prepared.trace_dir, stage)
    if points:
        return draw_point_kill(stage, points, sig, salt)
    return draw_timed_kill(stage, 1.0, sig, salt)  # no fault point (check_params): while it starts


def _params(names, *, slow: bool):
    marks = [pytest.mark.slow] if slow else []
    return [pytest.param(n, marks=marks, id=n) for n in names]


@pytest.mark.parametrize("stage", _params([s for s in SPECS if s in DEFAULT], slow=False)
                         + _params([s for s in SPECS if s not in DEFAULT], slow=True))
def test_stage_killed_once(prepared: Prepared, stage: str) -> None:
    prepared.ensure(stage)
    check_killed_stage(prepared, stage, _point_or_timed(prepared, stage, _default_signal(stage)))


@pytest.mark.slow
@pytest.mark.parametrize("stage", list(SPECS))
def test_stage_killed_after_a_delay(prepared: Prepared, stage: str) -> None:
    """The other signal, after a seeded delay within the stage's measured time: also the
    moments between fault points (inside a write, inside a worker pool, inside an import)."""
    prepared.ensure(stage)
    if stage not in prepared.seconds:  # run alone: measure the stage once
        t0 = time.monotonic()
        prepared.dvc("repro", "-s", "--force", stage)
        prepared.seconds[stage] = time.monotonic() - t0
    other = SIGNALS[1 - SIGNALS.index(_default_signal(stage))]
    check_killed_stage(prepared, stage, draw_timed_kill(stage, prepared.seconds[stage], other))
