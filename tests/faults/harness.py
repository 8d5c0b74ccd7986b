"""Kill a pipeline stage at a chosen point and look at what it leaves behind.

Kill points are the *fault points* of :mod:`blindspot.io` (the commit of every atomic write,
just before its rename, and every MLflow call of the stage runner): an undisturbed run with
``$BLINDSPOT_FAULT_TRACE`` lists a stage's points, a seeded draw picks one, and
``$BLINDSPOT_FAULT=<SIGNAL>@<k>`` makes the stage send itself the signal there. Why points
rather than a random delay: a delay mostly lands in imports or in the middle of a computation,
where nothing is at stake, and lands somewhere else on a busier machine; a point lands exactly
between two outputs, or between the outputs and the run's closing, every time, so a failure
reproduces. The timed kill (:attr:`Kill.after_s`, a seeded delay within the stage's measured
time) is kept for the slow suite, to also hit the moments between points (inside a write, inside
a worker pool).

What "undisturbed" means is a :class:`Snapshot` (md5 of every file of every declared out) taken
after the first ``dvc repro``; the training checkpoints are compared through a reader
(:data:`VOLATILE`), which also finds a torn one.
"""

from __future__ import annotations

import fnmatch
import hashlib
import io as _io
import json
import os
import re
import shlex
import shutil
import signal
import subprocess
import sys
import time
import zlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from random import Random

import yaml

from blindspot.io import FAULT_ENV, TEMP_MARK

SEED = 9  # issue 9


@dataclass(frozen=True)
class FaultPoint:
    """The k-th fault point of a traced run: its kind (write, mlflow) and what was being done."""

    k: int
    event: str
    detail: str


@dataclass(frozen=True)
class Kill:
    """Send ``signal`` at fault point ``k`` or, if ``k`` is None, ``after_s`` after the start."""

    signal: signal.Signals
    k: int | None = None
    after_s: float | None = None
    point: FaultPoint | None = None

    def __str__(self) -> str:
        if self.point is None:
            return f"{self.signal.name} at {self.after_s:.2f} s"
        what = re.sub(r"\S*/", "", self.point.detail)  # file names without their folders
        return f"{self.signal.name} at point {self.k} ({self.point.event} {what})"


def stage_specs(root: Path) -> dict[str, dict]:
    """The stages of ``root/dvc.yaml`` as written there, in order."""
    return yaml.safe_load((root / "dvc.yaml").read_text())["stages"]


def _paths(entries: list | None, *, persist: bool | None = None) -> list[str]:
    out = []
    for item in entries or ():
        path, opts = (next(iter(item.items())) if isinstance(item, dict) else (item, {}))
        if persist is None or bool((opts or {}).get("persist")) == persist:
            out.append(path)
    return out


def declared_outs(spec: Mapping, *, persist: bool | None = None) -> list[str]:
    """outs, metrics and plots of one dvc.yaml stage (``persist`` filters on that flag)."""
    return [p for key in ("outs", "metrics", "plots") for p in _paths(spec.get(key), persist=persist)]


def stage_command(spec: Mapping) -> list[str]:
    """The stage's ``cmd`` with ``python`` made this interpreter."""
    cmd = shlex.split(spec["cmd"])
    return [sys.executable, *cmd[1:]] if cmd[0] == "python" else cmd


# ---- what the undisturbed run wrote

def _md5(path: Path) -> str:
    return hashlib.md5(path.read_bytes()).hexdigest()


def _checkpoint(data: bytes) -> bytes:
    import torch

    blob = torch.load(_io.BytesIO(data), map_location="cpu", weights_only=False)
    state = {k: v.numpy().tobytes().hex() for k, v in blob["model"].items()}
    return json.dumps({"epoch": blob["epoch"], "model": state}, sort_keys=True).encode()


# Outputs compared through a reader, by glob pattern of their path: the training checkpoints
# (one per ensemble member, member<i>/last.pt, or one for a single network, last.pt), read as
# their epoch and weights, so a torn one is found unreadable. No output holds a wall time any
# more (MLflow has them), so every other output is compared byte for byte.
VOLATILE: dict[str, Callable[[bytes], bytes]] = {
    "data/train/checkpoints/last.pt": _checkpoint,
    "data/train/checkpoints/*/last.pt": _checkpoint,
}


def normaliser(rel: str) -> Callable[[bytes], bytes] | None:
    """The :data:`VOLATILE` normaliser whose pattern matches ``rel`` (``*`` within one folder),
    or None."""
    for pattern, norm in VOLATILE.items():
        if fnmatch.fnmatchcase(rel, pattern) and rel.count("/") == pattern.count("/"):
            return norm
    return None


def fingerprint(root: Path, rel: str) -> str:
    """md5 of a file's bytes, or of its normalised bytes if it is :data:`VOLATILE`."""
    data = (root / rel).read_bytes()
    norm = normaliser(rel)
    return hashlib.md5(norm(data) if norm else data).hexdigest()


def unreadable(root: Path, outs: list[str]) -> list[str]:
    """Files under ``outs`` that their :data:`VOLATILE` normaliser cannot read (a torn
    checkpoint), or, without a normaliser, that are empty (all that can be said of an unknown
    format)."""
    bad = []
    for rel in files_of(root, outs):
        norm = normaliser(rel)
        if norm is None:
            if (root / rel).stat().st_size == 0:
                bad.append(f"{rel}: empty (no reader known for it)")
            continue
        try:
            norm((root / rel).read_bytes())
        except Exception as exc:  # noqa: BLE001 - any failure to read it is the finding
            bad.append(f"{rel}: unreadable ({type(exc).__name__}: {exc})")
    return bad


def is_temp(path: Path) -> bool:
    """A temporary name of an atomic writer (blindspot.io's)."""
    return path.name.startswith(".") and TEMP_MARK in path.name


def files_of(root: Path, outs: list[str]) -> list[str]:
    """Files (not temporaries) under the declared ``outs``, relative to ``root``."""
    found = []
    for out in outs:
        p = root / out
        if p.is_file():
            found.append(out)
        elif p.is_dir():
            found += [f.relative_to(root).as_posix() for f in sorted(p.rglob("*"))
                      if f.is_file() and not any(is_temp(q) for q in f.relative_to(p).parents
                                                 if q.name) and not is_temp(f)]
    return found


def temp_debris(root: Path, outs: list[str]) -> list[Path]:
    """Temporaries next to or inside the declared ``outs``."""
    found = []
    for folder in {(root / o).parent for o in outs} | {root / o for o in outs if (root / o).is_dir()}:
        if folder.is_dir():
            found += [p for p in folder.rglob(".*") if is_temp(p)]
    return sorted(set(found))


@dataclass(frozen=True)
class Snapshot:
    """Fingerprints of every file of every declared out of each stage."""

    files: dict[str, dict[str, str]]  # stage -> {file: fingerprint}

    @classmethod
    def take(cls, root: Path, stages: Mapping[str, Mapping]) -> Snapshot:
        return cls({name: {f: fingerprint(root, f) for f in files_of(root, declared_outs(spec))}
                    for name, spec in stages.items()})

    def differences(self, root: Path, stage: str, outs: list[str], *, absent_ok: bool) -> list[str]:
        """What under ``outs`` differs from the snapshot (a file absent counts unless
        ``absent_ok``; a file the snapshot does not know always counts)."""
        want = self.files[stage]
        have = set(files_of(root, outs))
        problems = [f"{f}: not written by the undisturbed run" for f in sorted(have - set(want))]
        for f, digest in sorted(want.items()):
            if f not in have:
                if not absent_ok:
                    problems.append(f"{f}: missing")
            elif fingerprint(root, f) != digest:
                problems.append(f"{f}: present but not the undisturbed bytes")
        if absent_ok:  # a directory out must be whole or absent, never part of itself
            for out in outs:
                part = [f for f in want if f.startswith(out + "/")]
                present = [f for f in part if f in have]
                if present and len(present) != len(part):
                    problems.append(f"{out}/: directory holds {len(present)} of {len(part)} files")
        return problems


# ---- traces and kill points

def read_trace(trace_dir: Path, stage: str) -> list[FaultPoint]:
    """The fault points of the last traced run of ``stage`` (``stages/<stage>.py``)."""
    best: tuple[float, list[FaultPoint]] | None = None
    for path in trace_dir.glob("*.trace"):
        head, *lines = path.read_text().splitlines()
        if not re.search(rf"[ /]stages/{re.escape(stage)}\.py\b", head):
            continue
        points = []
        for line in lines:
            k, _t, event, *detail = line.split(" ", 3)
            points.append(FaultPoint(int(k), event, detail[0] if detail else ""))
        mtime = path.stat().st_mtime
        if best is None or mtime > best[0]:
            best = (mtime, points)
    return [] if best is None else best[1]


def rng_for(stage: str, salt: str = "") -> Random:
    """A random generator seeded by the stage's name: the same draw on every machine."""
    return Random(SEED * 1_000_003 + zlib.crc32(f"{stage}/{salt}".encode()))


def draw_point_kill(stage: str, points: list[FaultPoint], sig: signal.Signals,
                    salt: str = "") -> Kill:
    """A kill at a fault point drawn uniformly among the stage's points (all but the last, the
    closing of the run, after which there is nothing left to interrupt)."""
    choices = points[:-1] or points
    point = rng_for(stage, salt + sig.name).choice(choices)
    return Kill(sig, k=point.k, point=point)


def draw_timed_kill(stage: str, seconds: float, sig: signal.Signals, salt: str = "") -> Kill:
    """A kill after a delay drawn uniformly in (0, ``seconds``)."""
    return Kill(sig, after_s=rng_for(stage, salt + sig.name).uniform(0.05, 0.95) * seconds)


@dataclass
class Killed:
    """How the killed process ended."""

    pid: int
    returncode: int
    stdout: str
    stderr: str
    seconds: float
    survivors: list[int]  # processes of its group still alive after it died (leaked workers)


def run_killed(root: Path, spec: Mapping, kill: Kill, env: dict[str, str]) -> Killed:
    """Run the stage's command as ``dvc repro --force`` would (non-persistent outs removed
    first), with ``kill`` armed, in its own process group; wait for it to die."""
    for out in declared_outs(spec, persist=False):
        p = root / out
        if p.is_dir():
            shutil.rmtree(p)
        elif p.exists():
            p.unlink()
    env = dict(env)
    if kill.k is not None:
        env[FAULT_ENV] = f"{kill.signal.name.removeprefix('SIG')}@{kill.k}"
    t0 = time.monotonic()
    proc = subprocess.Popen(stage_command(spec), cwd=root, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)
    if kill.after_s is not None:
        try:
            proc.wait(timeout=kill.after_s)
        except subprocess.TimeoutExpired:
            proc.send_signal(kill.signal)
    out, err = proc.communicate(timeout=900)
    seconds = time.monotonic() - t0
    return Killed(proc.pid, proc.returncode, out, err, seconds, _group_survivors(proc.pid))


def _group_survivors(pgid: int, grace_s: float = 5.0) -> list[int]:
    """Live processes of process group ``pgid`` (workers the dead stage left behind), after
    waiting up to ``grace_s`` for them to notice; the survivors are then killed."""
    deadline = time.monotonic() + grace_s
    while True:
        alive = [int(p.name) for p in Path("/proc").iterdir() if p.name.isdigit()
                 and _pgid(int(p.name)) == pgid]
        if not alive or time.monotonic() > deadline:
            break
        time.sleep(0.2)
    for pid in alive:
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    return alive


def _pgid(pid: int) -> int | None:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    fields = stat.rpartition(")")[2].split()
    return int(fields[2]) if fields[0] != "Z" else None
