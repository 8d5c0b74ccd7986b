"""Test helpers that start, and always stop, the services a scale-out test needs on this machine
only: a Ray head and a PostgreSQL-backed MLflow tracking server, each bound to 127.0.0.1 on a
free port, each in its own process group so that stopping it ends exactly what it started.

The same code is what ``python -m blindspot.runs.server`` runs (see README, "Scale out").
"""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import subprocess
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

from tests.pipeline.toy_repo import VENV_BIN, clean_env


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def wait_for_port(port: int, proc: subprocess.Popen, what: str, timeout_s: float = 120) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            raise RuntimeError(f"{what} exited {proc.returncode} before listening on {port}")
        with contextlib.suppress(OSError), socket.create_connection(("127.0.0.1", port), 1):
            return
        time.sleep(0.5)
    raise TimeoutError(f"{what} not listening on 127.0.0.1:{port} after {timeout_s} s")


def stop_group(proc: subprocess.Popen, timeout_s: float = 60) -> None:
    """SIGTERM the process group ``proc`` leads (started with start_new_session), then SIGKILL
    what is left of it."""
    with contextlib.suppress(ProcessLookupError):
        os.killpg(proc.pid, signal.SIGTERM)
    try:
        proc.wait(timeout_s)
    except subprocess.TimeoutExpired:
        pass
    with contextlib.suppress(ProcessLookupError):
        os.killpg(proc.pid, signal.SIGKILL)
    proc.wait(10)


@contextlib.contextmanager
def ray_head(num_cpus: int = 2) -> Iterator[str]:
    """A Ray head on 127.0.0.1 (no dashboard), yielding its address ``127.0.0.1:PORT``."""
    port = free_port()
    temp = Path(tempfile.mkdtemp(prefix="ray", dir="/tmp"))  # short: Ray's socket paths
    env = clean_env(RAY_USAGE_STATS_ENABLED="0")
    proc = subprocess.Popen(
        [str(VENV_BIN / "ray"), "start", "--head", "--block", "--node-ip-address=127.0.0.1",
         f"--port={port}", f"--num-cpus={num_cpus}", "--include-dashboard=false",
         "--disable-usage-stats", f"--temp-dir={temp}"],
        env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        wait_for_port(port, proc, "the Ray head (GCS)")
        yield f"127.0.0.1:{port}"
    finally:
        stop_group(proc)
        import shutil

        shutil.rmtree(temp, ignore_errors=True)
