"""A shared MLflow tracking server on PostgreSQL, started on this machine for a team or a cluster.

SQLite (``<repo>/mlflow.db``) stays the store of one machine. When sweep jobs run on other
machines (Ray, SLURM), or several people share runs, they log to one server instead::

    python -m blindspot.runs.server start [--dir .mlflow-server] [--host 127.0.0.1]
    export MLFLOW_TRACKING_URI=http://127.0.0.1:<port>   # printed by `start`
    python -m blindspot train -m hydra/launcher=ray_cluster model.hidden_size=32,64
    python -m blindspot.runs.server stop [--dir .mlflow-server]

``start`` creates a PostgreSQL 15 cluster in ``<dir>/pg`` (``initdb``; trust authentication,
listening on ``--host`` only, on a free port) and a database ``mlflow``, then runs
``mlflow server`` with that database as its backend store and ``<dir>/artifacts`` as its artifact
store (proxied: clients upload through the server, ``mlflow-artifacts:/`` URIs), so jobs need no
access to the server's disk. The ports and pids are in ``<dir>/server.json``; ``stop`` ends what
``start`` started, by pid. A team's existing server needs none of this: set
``MLFLOW_TRACKING_URI`` (or ``runs.uri`` in conf/runs/) to its address.

PostgreSQL refuses to run as root; under root the database runs as the ``postgres`` system user
(Debian's package creates it) and ``<dir>/pg`` belongs to it. Binaries: ``$BLINDSPOT_PG_BIN``,
else ``pg_config --bindir``, else ``/usr/lib/postgresql/<newest>/bin``.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

__all__ = ["ServerInfo", "pg_bin_dir", "start", "stop", "main"]

STATE_FILE = "server.json"


@dataclass(frozen=True)
class ServerInfo:
    """What :func:`start` started: the tracking URI and what :func:`stop` needs."""

    tracking_uri: str
    backend_store_uri: str
    artifacts: str
    pg_port: int
    pg_data: str
    mlflow_pid: int


def pg_bin_dir() -> Path:
    """The folder of PostgreSQL's ``initdb``/``pg_ctl``; ``FileNotFoundError`` saying where it
    looked (set ``BLINDSPOT_PG_BIN``) when there is none."""
    tried = []
    env = os.environ.get("BLINDSPOT_PG_BIN")
    candidates = [Path(env)] if env else []
    with contextlib.suppress(OSError, subprocess.SubprocessError):
        out = subprocess.run(["pg_config", "--bindir"], capture_output=True, text=True, check=True)
        candidates.append(Path(out.stdout.strip()))
    versions = sorted(Path("/usr/lib/postgresql").glob("*/bin"),
                      key=lambda p: int(p.parent.name) if p.parent.name.isdigit() else 0)
    candidates += versions[::-1]
    for folder in candidates:
        tried.append(str(folder))
        if (folder / "initdb").is_file() and (folder / "pg_ctl").is_file():
            return folder
    raise FileNotFoundError(
        f"PostgreSQL's initdb/pg_ctl not found (looked in {', '.join(tried) or 'nothing'}); "
        "install PostgreSQL (Debian: apt-get install postgresql) or set BLINDSPOT_PG_BIN")


def free_port(host: str) -> int:
    with socket.socket() as s:
        s.bind((host, 0))
        return int(s.getsockname()[1])


def _as_db_user(cmd: Sequence[str]) -> list[str]:
    """``cmd`` run as the ``postgres`` user when this process is root (PostgreSQL refuses root)."""
    if os.geteuid() != 0:
        return list(cmd)
    runuser = shutil.which("runuser")
    if runuser is None:
        raise RuntimeError("running as root and `runuser` not found: PostgreSQL refuses to run "
                           "as root; start the server as an ordinary user")
    return [runuser, "-u", "postgres", "--", *cmd]


def _run(cmd: list[str], what: str) -> None:
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        hint = (" (PostgreSQL runs as the postgres user here: every folder above the data "
                "folder must be searchable by it)" if os.geteuid() == 0 else "")
        raise RuntimeError(f"{what} exited {proc.returncode}{hint}: "
                           f"{(proc.stderr or proc.stdout).strip()}")


def _wait_listening(host: str, port: int, proc: subprocess.Popen | None, what: str,
                    timeout_s: float) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if proc is not None and proc.poll() is not None:
            raise RuntimeError(f"{what} exited {proc.returncode} before listening on {host}:{port}")
        with contextlib.suppress(OSError), socket.create_connection((host, port), 1):
            return
        time.sleep(0.3)
    raise TimeoutError(f"{what} not listening on {host}:{port} after {timeout_s:.0f} s")


def start(folder: str | os.PathLike[str], host: str = "127.0.0.1", port: int | None = None,
          timeout_s: float = 120) -> ServerInfo:
    """Start PostgreSQL (a new cluster in ``<folder>/pg``, or the one there) and an MLflow
    server on it; returns the :class:`ServerInfo` also written to ``<folder>/server.json``.

    Raises ``FileExistsError`` if ``<folder>/server.json`` names a server still running,
    ``RuntimeError``/``TimeoutError`` naming the program that did not come up (its log is in
    ``<folder>``)."""
    folder = Path(folder).resolve()
    folder.mkdir(parents=True, exist_ok=True)
    state = folder / STATE_FILE
    if state.is_file():
        old = ServerInfo(**json.loads(state.read_text()))
        if _alive(old.mlflow_pid):
            raise FileExistsError(f"{state}: a server started there still runs (pid "
                                  f"{old.mlflow_pid}, {old.tracking_uri}); stop it first")
    bindir = pg_bin_dir()
    data = folder / "pg"
    if os.geteuid() == 0:  # the database files belong to the user that runs PostgreSQL
        os.chmod(folder, 0o755)
    if not (data / "PG_VERSION").is_file():
        data.mkdir(exist_ok=True)
        if os.geteuid() == 0:
            shutil.chown(data, "postgres", "postgres")
        _run(_as_db_user([str(bindir / "initdb"), "-D", str(data), "-U", "mlflow", "--auth=trust",
                          "-E", "UTF8", "--no-instructions"]), "initdb")
    pg_port = free_port(host)
    log = data / "postgres.log"
    _run(_as_db_user([str(bindir / "pg_ctl"), "-D", str(data), "-l", str(log), "-w", "-t",
                      str(int(timeout_s)), "start", "-o", f"-h {host} -p {pg_port} -k {data}"]),
         f"pg_ctl start (log {log})")
    created = subprocess.run(
        _as_db_user([str(bindir / "createdb"), "-h", host, "-p", str(pg_port), "-U", "mlflow",
                     "mlflow"]), capture_output=True, text=True)
    if created.returncode != 0 and "already exists" not in created.stderr:
        raise RuntimeError(f"createdb mlflow on {host}:{pg_port} failed: {created.stderr}")
    backend = f"postgresql+psycopg2://mlflow@{host}:{pg_port}/mlflow"
    artifacts = folder / "artifacts"
    artifacts.mkdir(exist_ok=True)
    port = port or free_port(host)
    env = {k: v for k, v in os.environ.items() if not k.startswith("MLFLOW_")}
    mlflow_bin = Path(sys.executable).with_name("mlflow")
    with open(folder / "mlflow-server.log", "ab") as out:
        proc = subprocess.Popen(
            [str(mlflow_bin), "server", "--backend-store-uri", backend,
             "--artifacts-destination", artifacts.as_uri(), "--serve-artifacts",
             "--host", host, "--port", str(port), "--workers", "2"],
            stdout=out, stderr=subprocess.STDOUT, env=env, start_new_session=True)
    info = ServerInfo(f"http://{host}:{port}", backend, artifacts.as_uri(), pg_port, str(data),
                      proc.pid)
    state.write_text(json.dumps(asdict(info), indent=2))
    try:
        _wait_listening(host, port, proc, f"mlflow server (log {folder / 'mlflow-server.log'})",
                        timeout_s)
    except BaseException:
        stop(folder)
        raise
    return info


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def stop(folder: str | os.PathLike[str], timeout_s: float = 60) -> bool:
    """Stop the MLflow server (its process group, by the pid in ``server.json``) and PostgreSQL
    (``pg_ctl stop``) started in ``folder``; False when nothing was started there."""
    folder = Path(folder).resolve()
    state = folder / STATE_FILE
    if not state.is_file():
        return False
    info = ServerInfo(**json.loads(state.read_text()))
    if _alive(info.mlflow_pid):
        with contextlib.suppress(ProcessLookupError):
            os.killpg(info.mlflow_pid, signal.SIGTERM)
        deadline = time.monotonic() + timeout_s
        while _alive(info.mlflow_pid) and time.monotonic() < deadline:
            with contextlib.suppress(ChildProcessError):
                os.waitpid(info.mlflow_pid, os.WNOHANG)
            time.sleep(0.2)
        with contextlib.suppress(ProcessLookupError):
            os.killpg(info.mlflow_pid, signal.SIGKILL)
    if (Path(info.pg_data) / "postmaster.pid").is_file():
        subprocess.run(_as_db_user([str(pg_bin_dir() / "pg_ctl"), "-D", info.pg_data, "-m",
                                    "fast", "-w", "stop"]), capture_output=True, text=True)
    state.unlink()
    return True


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m blindspot.runs.server {start,stop}``."""
    parser = argparse.ArgumentParser(prog="python -m blindspot.runs.server",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("command", choices=["start", "stop"])
    parser.add_argument("--dir", default=".mlflow-server",
                        help="folder of the database, the artifacts and the logs")
    parser.add_argument("--host", default="127.0.0.1",
                        help="address to listen on (0.0.0.0 for a team's network: no auth!)")
    parser.add_argument("--port", type=int, default=None, help="MLflow's port (default: free)")
    args = parser.parse_args(argv)
    if args.command == "stop":
        print("stopped" if stop(args.dir) else f"nothing started in {args.dir}")
        return 0
    info = start(args.dir, args.host, args.port)
    print(f"MLflow server on PostgreSQL: {info.tracking_uri} (database {info.backend_store_uri},"
          f" artifacts {info.artifacts})\nexport MLFLOW_TRACKING_URI={info.tracking_uri}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
