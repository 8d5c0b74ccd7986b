"""The pieces the kill harness relies on, each on its own and fast: fault points that kill at
the k-th write, the sweep of a dead writer's temporary files, and the closing of runs left
RUNNING by a SIGKILLed process."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from mlflow.tracking import MlflowClient

from blindspot import io, runs
from tests.pipeline.toy_repo import blindspot, clean_env, make_toy_repo, logged_runs

WRITER = """
import sys
from blindspot import io
for name in ("a.txt", "b.txt", "c.txt"):
    io.write_text(name, name)
"""

KILLED_RUN = """
import sys
from blindspot import io, runs
with runs.stage_run("victim", {"x": 1}, repo_root=sys.argv[1]) as t:
    t.log_metrics({"m": 1.0})
    io.write_text("out.txt", "never")
"""


def _run(code: str, cwd: Path, **env: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-c", code, str(cwd)], cwd=cwd, capture_output=True,
                          text=True, env=clean_env(**env), timeout=120)


def test_kill_at_the_kth_write_leaves_earlier_files_whole(tmp_path: Path) -> None:
    proc = _run(WRITER, tmp_path, BLINDSPOT_FAULT="KILL@2",
                BLINDSPOT_FAULT_TRACE=str(tmp_path / "trace"))
    assert proc.returncode == -signal.SIGKILL, proc.stderr
    assert (tmp_path / "a.txt").read_text() == "a.txt"
    assert not (tmp_path / "b.txt").exists() and not (tmp_path / "c.txt").exists()
    (debris,) = [p for p in tmp_path.iterdir() if io.TEMP_MARK in p.name]
    assert debris.name.startswith(".b.tmp-") and (debris / "b.txt").read_text() == "b.txt"
    (trace,) = (tmp_path / "trace").glob("*.trace")
    head, *points = trace.read_text().splitlines()
    assert head.startswith("cmd ") and [p.split()[2] for p in points] == ["write", "write"]
    assert points[1].endswith("b.txt")
    # The next start removes the dead writer's temporary file, never a live writer's.
    live = tmp_path / f".c{io.TEMP_MARK}{os.getpid()}-abcd"
    live.mkdir()
    assert io.remove_stale_temps([tmp_path / "b.txt", tmp_path / "c.txt"]) == [debris]
    assert live.exists()


def test_term_at_a_write_removes_the_temporary_file(tmp_path: Path) -> None:
    code = "from blindspot.runs import sigterm_as_exit\nwith sigterm_as_exit():\n" + "".join(
        "    " + line + "\n" for line in WRITER.strip().splitlines())
    proc = _run(code, tmp_path, BLINDSPOT_FAULT="TERM@3")
    assert proc.returncode == 143, proc.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt", "b.txt"]


def test_a_bad_fault_spec_names_the_variable(tmp_path: Path) -> None:
    proc = _run(WRITER, tmp_path, BLINDSPOT_FAULT="KILL-2")
    assert proc.returncode == 1 and "$BLINDSPOT_FAULT='KILL-2': expected <SIGNAL>@<k>" in proc.stderr


def test_run_of_a_sigkilled_process_is_closed_killed_on_the_next_start(tmp_path: Path) -> None:
    toy = make_toy_repo(tmp_path / "repo")
    # points: open store, experiment, create run, params, (log_text is no point),
    # metrics, then the write: kill at the write, inside the run
    trace = _run(KILLED_RUN, toy, BLINDSPOT_FAULT_TRACE=str(tmp_path / "t"))
    assert trace.returncode == 0, trace.stderr
    (path,) = (tmp_path / "t").glob("*.trace")
    k = next(int(line.split()[0]) for line in path.read_text().splitlines()[1:]
             if line.split()[2] == "write")
    proc = _run(KILLED_RUN, toy, BLINDSPOT_FAULT=f"KILL@{k}")
    assert proc.returncode == -signal.SIGKILL, proc.stderr
    victim = logged_runs(toy)[-1]
    pid = victim.data.tags["blindspot.pid"]
    assert victim.info.status == "RUNNING" and victim.data.tags["blindspot.stage"] == "victim"
    # A RUNNING run of a live process (this one) is left alone; a recycled pid is recognised.
    client = MlflowClient(tracking_uri=f"sqlite:///{toy / 'mlflow.db'}")
    exp = victim.info.experiment_id
    live = client.create_run(exp, tags=runs.stale.owner_tags())
    recycled = client.create_run(exp, tags={**runs.stale.owner_tags(),
                                            runs.stale.PID_START_TAG: "1"})
    out = blindspot(["cleanup"], toy).stdout
    assert out.startswith("closed 2 stale run(s) KILLED"), out
    status = {r.info.run_id: r.info.status for r in logged_runs(toy)}
    assert status[victim.info.run_id] == "KILLED" and status[recycled.info.run_id] == "KILLED"
    assert status[live.info.run_id] == "RUNNING"
    note = client.get_run(victim.info.run_id).data.tags[runs.stale.CLOSED_TAG]
    assert f"process {pid} " in note and "closed KILLED" in note
    client.set_terminated(live.info.run_id)


POOL = """
import os, sys, time
from concurrent.futures import ProcessPoolExecutor
import multiprocessing as mp
from blindspot import runs
runs.children_die_with_this_process()
def work(i):
    time.sleep(60)
with ProcessPoolExecutor(2, mp_context=mp.get_context("fork")) as pool:
    futures = [pool.submit(work, i) for i in range(2)]
    time.sleep(1)
    print(" ".join(str(p) for p in pool._processes), flush=True)
    os.kill(os.getpid(), 9)
"""


def test_pool_workers_die_with_a_sigkilled_stage(tmp_path: Path) -> None:
    proc = _run(POOL, tmp_path)
    assert proc.returncode == -signal.SIGKILL, proc.stderr
    workers = [int(p) for p in proc.stdout.split()]
    assert len(workers) == 2
    deadline = time.time() + 10
    while any(Path(f"/proc/{p}").exists() and "Z" not in _state(p) for p in workers):
        assert time.time() < deadline, f"workers {workers} outlived their SIGKILLed parent"
        time.sleep(0.1)


def _state(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rpartition(")")[2].split()[0]
    except OSError:
        return "Z"
