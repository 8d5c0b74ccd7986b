"""Atomic output helpers: a killed stage never leaves a half-written file that looks complete.

Every writer writes into a hidden temporary folder in the *same directory* as the target (so the
final ``os.replace`` is a rename on one file system, atomic on POSIX), under the target's own
name, flushes and ``fsync``s the data, renames it into place and ``fsync``s the directory. On any
exception (including the ``SystemExit`` raised by the SIGTERM handler of
:mod:`blindspot.runs`) the temporary folder is removed and the previous target, if any, is
left untouched.

The temporary file keeps the target's very name (``.fig04.tmp-<pid>-<token>/fig04.png``): libraries
that infer the format from the extension (matplotlib ``savefig``, pandas) still work, and those
that record the file name inside the file (``torch.save`` names its zip archive's root after it)
give the same bytes on every run.

Public API::

    atomic_path(path) -> ContextManager[Path]        # write to the yielded path yourself
    atomic_open(path, mode="w", **open_kw) -> ContextManager[IO]
    atomic_dir(path) -> ContextManager[Path]         # fill the yielded directory
    write_text(path, text) -> Path
    write_bytes(path, data) -> Path
    write_json(path, obj, *, indent=2) -> Path       # sorted keys, numpy-aware, no NaN
    write_yaml(path, obj) -> Path
    write_parquet(path, df, *, index=False, **kw) -> Path
    save_figure(fig, path, **savefig_kw) -> Path
    all_or_none() -> ContextManager[None]            # every write inside lands together, or none
    write_now() -> ContextManager[None]              # writes inside land at once (checkpoints)
    remove_stale_temps(paths) -> list[Path]         # temp files of writers that died (SIGKILL)
    fault_point(event, detail)                       # where a test may kill the process

Inside :func:`all_or_none` (the stage runner wraps every stage in it) each writer stops short of
its rename: the complete temporary file (or folder) waits, under its hidden name, until the whole
block succeeds, and then every one is renamed into place, in the order written; if the block
raises (or is stopped by SIGTERM), every waiting temporary is removed and no target changes. A
stage that handles several recordings or scenes, or writes several figures, so leaves all of its
outputs or none, never the first recordings' new files beside the others' old ones. Files that
must land at once, such as a training run's resume checkpoint, are written inside
:func:`write_now`.

A SIGKILL cannot be caught, so its temporary file stays behind. Such debris can never be taken
for an output: its folder's name is hidden and marked (``.<stem>.tmp-<pid>-<token>``, matched by
``.dvcignore`` so DVC never counts it inside a directory output), and the next stage run removes
the temporaries of dead writers (:func:`remove_stale_temps`, called by the stage runner).

Fault injection (for tests, see ``tests/faults/``): every commit of an atomic write and every
MLflow call of the stage runner is a *fault point*. ``BLINDSPOT_FAULT=<SIGNAL>@<k>`` (``KILL@3``,
``TERM@7``) makes the process send itself that signal at its k-th fault point (1-based; the main
process only, never a worker); ``BLINDSPOT_FAULT_TRACE=<dir>`` appends one line per fault point
to ``<dir>/<pid>.trace`` (first line: the command), so a test can count a stage's points in an
undisturbed run and then kill it at a chosen one, deterministically.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import secrets
import shutil
import signal
import sys
import time
from collections.abc import Iterable, Iterator, Mapping
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

if TYPE_CHECKING:  # pragma: no cover - typing only
    import pandas as pd
    from matplotlib.figure import Figure

__all__ = [
    "atomic_path",
    "atomic_open",
    "atomic_dir",
    "write_text",
    "write_bytes",
    "write_json",
    "write_yaml",
    "write_parquet",
    "save_figure",
    "all_or_none",
    "write_now",
    "to_jsonable",
    "remove_stale_temps",
    "fault_point",
    "FAULT_ENV",
    "FAULT_TRACE_ENV",
    "TEMP_MARK",
]

PathLike = str | os.PathLike[str]

TEMP_MARK = ".tmp-"
"""Marks a temporary name: ``.<stem>.tmp-<pid>-<token>`` (the pattern in ``.dvcignore``)."""
FAULT_ENV = "BLINDSPOT_FAULT"
FAULT_TRACE_ENV = "BLINDSPOT_FAULT_TRACE"


def _temp_sibling(target: Path) -> Path:
    """Hidden, unique name next to ``target`` that names the writer's pid."""
    token = secrets.token_hex(4)
    stem = target.stem if target.suffix else target.name
    return target.with_name(f".{stem}{TEMP_MARK}{os.getpid()}-{token}")


def _temp_writer_pid(name: str) -> int | None:
    """The writer's pid encoded in a temporary name of :func:`_temp_sibling`, else None."""
    if not name.startswith(".") or TEMP_MARK not in name:
        return None
    pid, _, rest = name.rpartition(TEMP_MARK)[2].partition("-")
    return int(pid) if pid.isdigit() and rest else None


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # someone else's live process
        return True
    return True


def remove_stale_temps(paths: Iterable[PathLike]) -> list[Path]:
    """Remove the temporary files/folders that writers now dead left next to (or, for a
    directory, inside) each of ``paths``; returns what was removed.

    A temporary name carries its writer's pid; one whose process still lives (a parallel writer)
    is kept. Called by the stage runner before a stage, so debris of a SIGKILLed run never
    accumulates next to the outputs.
    """
    removed: list[Path] = []
    folders: set[Path] = set()
    for path in map(Path, paths):
        folders.add(path.parent)
        if path.is_dir() and not path.is_symlink():
            folders.update(Path(root) for root, _dirs, _files in os.walk(path))
    for folder in sorted(folders):
        if not folder.is_dir():
            continue
        for entry in folder.iterdir():
            pid = _temp_writer_pid(entry.name)
            if pid is not None and pid != os.getpid() and not _pid_alive(pid):
                _remove(entry)
                removed.append(entry)
    return removed


class _Faults:
    """The armed fault (``$BLINDSPOT_FAULT``) and the fault-point counter of this process."""

    def __init__(self) -> None:
        self.count = 0
        self.pid = os.getpid()

    def hit(self, event: str, detail: str) -> None:
        spec = os.environ.get(FAULT_ENV)
        trace = os.environ.get(FAULT_TRACE_ENV)
        if not (spec or trace) or _in_worker():
            return
        if os.getpid() != self.pid:  # a forked child counts its own points
            self.count, self.pid = 0, os.getpid()
        self.count += 1
        if trace:
            _append_trace(Path(trace), self.count, event, detail)
        if spec:
            sig, k = _parse_fault(spec)
            if k == self.count:
                os.kill(os.getpid(), sig)


def _in_worker() -> bool:
    import multiprocessing

    return multiprocessing.parent_process() is not None


def _parse_fault(spec: str) -> tuple[int, int]:
    name, _, k = spec.partition("@")
    try:
        sig = signal.Signals["SIG" + name.upper().removeprefix("SIG")]
        return int(sig), int(k)
    except (KeyError, ValueError):
        raise ValueError(f"${FAULT_ENV}={spec!r}: expected <SIGNAL>@<k>, e.g. KILL@3 or TERM@7 "
                         "(k = the 1-based fault point at which to send the signal)") from None


def _append_trace(folder: Path, k: int, event: str, detail: str) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{os.getpid()}.trace"
    head = "" if path.exists() else "cmd " + " ".join(sys.argv) + "\n"
    with open(path, "a", encoding="utf-8") as fh:
        fh.write(f"{head}{k} {time.time():.3f} {event} {detail}\n")


_FAULTS = _Faults()


def fault_point(event: str, detail: str = "") -> None:
    """A point where a test may kill this process (see the module docstring); a no-op unless
    ``$BLINDSPOT_FAULT`` or ``$BLINDSPOT_FAULT_TRACE`` is set. ``event`` names the kind
    (``write``, ``mlflow``), ``detail`` what is being done (the target path, the call)."""
    _FAULTS.hit(event, detail)


def _fsync_file(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _fsync_dir(path: Path) -> None:
    """fsync a directory so a rename inside it survives a crash (no-op where unsupported)."""
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:  # pragma: no cover - e.g. Windows
        return
    try:
        os.fsync(fd)
    except OSError:  # pragma: no cover - some file systems refuse directory fsync
        pass
    finally:
        os.close(fd)


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        with contextlib.suppress(FileNotFoundError):
            path.unlink()


class _Group:
    """The writes of an :func:`all_or_none` block: (temporary, target, its hidden folder or
    None for a directory) in the order completed, renamed into place when the block ends."""

    def __init__(self) -> None:
        self.pid = os.getpid()
        self.pending: list[tuple[Path, Path, Path | None]] = []
        self.paused = 0


_GROUPS: list[_Group] = []
_FILLING: list[Path] = []     # temporary folders of atomic_dir blocks being filled


def _open_group(target: Path | None = None) -> _Group | None:
    """The innermost :func:`all_or_none` block of this process that is not paused by
    :func:`write_now`, else None (a forked worker inherits its parent's block but never ends
    it, so it writes at once). A ``target`` inside a folder :func:`atomic_dir` is filling is
    written at once: that folder is what waits."""
    if not (_GROUPS and _GROUPS[-1].pid == os.getpid() and not _GROUPS[-1].paused):
        return None
    if target is not None and any(f == target or f in target.parents for f in _FILLING):
        return None
    return _GROUPS[-1]


@contextlib.contextmanager
def all_or_none() -> Iterator[None]:
    """Every atomic write inside the block lands together when the block succeeds, or none does.

    Writers (:func:`atomic_path` and all built on it, :func:`atomic_dir`) leave their complete
    temporaries in place; at the end of a successful block they are renamed onto their targets
    in the order written (each rename a fault point). On an exception (SIGTERM's SystemExit,
    KeyboardInterrupt included) the temporaries are removed and every target keeps its previous
    content. Nested blocks join the outermost one.
    """
    if _GROUPS and _GROUPS[-1].pid == os.getpid():
        yield                                 # joins the enclosing block
        return
    group = _Group()
    _GROUPS.append(group)
    try:
        yield
    except BaseException:
        _GROUPS.remove(group)
        for tmp, _target, folder in group.pending:
            _remove(folder if folder is not None else tmp)
        raise
    _GROUPS.remove(group)
    try:
        while group.pending:
            tmp, target, folder = group.pending[0]
            if folder is None:
                _commit_dir(tmp, target)
            else:
                _commit_file(tmp, target)
                _remove(folder)
            group.pending.pop(0)
    finally:
        for tmp, _target, folder in group.pending:  # a rename failed: the rest is not written
            _remove(folder if folder is not None else tmp)


@contextlib.contextmanager
def write_now() -> Iterator[None]:
    """Writes inside the block land at once even within :func:`all_or_none` (a training run's
    resume checkpoint must survive the run being killed)."""
    group = _GROUPS[-1] if _GROUPS and _GROUPS[-1].pid == os.getpid() else None
    if group is not None:
        group.paused += 1
    try:
        yield
    finally:
        if group is not None:
            group.paused -= 1


def _commit_file(tmp: Path, target: Path) -> None:
    fault_point("write", str(target))
    os.replace(tmp, target)
    _fsync_dir(target.parent)


def _commit_dir(tmp: Path, target: Path) -> None:
    """Rename the complete directory ``tmp`` onto ``target``, the old one moved aside first and
    removed after (put back if the second rename fails)."""
    fault_point("write", str(target))
    old: Path | None = None
    try:
        if target.exists() or target.is_symlink():
            old = _temp_sibling(target)
            os.replace(target, old)
        os.replace(tmp, target)
        _fsync_dir(target.parent)
    except BaseException:
        _remove(tmp)
        if old is not None and not target.exists():
            os.replace(old, target)  # put the previous version back
            old = None
        raise
    finally:
        if old is not None:
            _remove(old)


@contextlib.contextmanager
def atomic_path(path: PathLike) -> Iterator[Path]:
    """Yield a temporary path with the name of ``path``, in a hidden folder next to it; on
    success rename it onto ``path``.

    The caller writes the file at the yielded path (any library, any format). Parent
    directories are created. If the body raises, the temporary folder is deleted and ``path`` is
    left as it was. Raises ``FileNotFoundError`` naming the path if the body wrote nothing.
    """
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    folder = _temp_sibling(target)
    folder.mkdir()
    tmp = folder / target.name
    waiting = False
    try:
        yield tmp
        if not tmp.exists():
            raise FileNotFoundError(
                f"atomic write of {target}: nothing was written to the temporary file {tmp}"
            )
        if tmp.is_dir():
            raise IsADirectoryError(
                f"atomic write of {target}: a directory was written; use atomic_dir() for that"
            )
        _fsync_file(tmp)
        group = _open_group(target)
        if group is not None:        # renamed when the all_or_none block succeeds
            group.pending.append((tmp, target, folder))
            waiting = True
        else:
            _commit_file(tmp, target)
    finally:
        if not waiting:
            _remove(folder)


@contextlib.contextmanager
def atomic_open(path: PathLike, mode: str = "w", **open_kwargs: Any) -> Iterator[IO[Any]]:
    """``open()`` for writing, atomically: the file appears at ``path`` only when complete.

    ``mode`` must be a write mode (``"w"``, ``"wb"``, ``"x"``...); text mode defaults to UTF-8.
    """
    if not any(c in mode for c in "wx") or "+" in mode or "a" in mode:
        raise ValueError(f"atomic_open({path!s}): mode must be 'w'/'wb'/'x', got {mode!r}")
    mode = mode.replace("x", "w")
    if "b" not in mode:
        open_kwargs.setdefault("encoding", "utf-8")
    with atomic_path(path) as tmp, open(tmp, mode, **open_kwargs) as fh:
        yield fh
        fh.flush()


@contextlib.contextmanager
def atomic_dir(path: PathLike) -> Iterator[Path]:
    """Yield an empty temporary directory next to ``path``; on success it replaces ``path``.

    Files written inside are fsynced, then an existing ``path`` is moved aside and the new
    directory renamed into place (two renames: a crash between them leaves ``path`` absent,
    never half-filled), and the old one removed. On error the temporary directory is removed
    and ``path`` is untouched.
    """
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = _temp_sibling(target)
    tmp.mkdir()
    _FILLING.append(tmp)
    try:
        yield tmp
        for root, _dirs, files in os.walk(tmp):
            for name in files:
                _fsync_file(Path(root, name))
            _fsync_dir(Path(root))
    except BaseException:
        _remove(tmp)
        raise
    finally:
        _FILLING.remove(tmp)
    group = _open_group(target)
    if group is not None:            # renamed when the all_or_none block succeeds
        group.pending.append((tmp, target, None))
    else:
        _commit_dir(tmp, target)


def write_bytes(path: PathLike, data: bytes) -> Path:
    """Atomically write ``data`` to ``path``; returns the path."""
    with atomic_open(path, "wb") as fh:
        fh.write(data)
    return Path(path)


def write_text(path: PathLike, text: str) -> Path:
    """Atomically write UTF-8 ``text`` (newline characters written as given); returns the path."""
    with atomic_open(path, "w", newline="") as fh:
        fh.write(text)
    return Path(path)


def to_jsonable(obj: Any, where: str = "$") -> Any:
    """Convert numpy scalars/arrays, Paths, tuples and OmegaConf containers to plain JSON types.

    Raises ``ValueError`` naming the offending key path (``where``) for NaN/inf (not valid JSON)
    or unsupported types.
    """
    if obj is None or isinstance(obj, bool | str):
        return obj
    if isinstance(obj, int):
        return int(obj)
    if isinstance(obj, float):
        if not math.isfinite(obj):
            raise ValueError(f"{where}: {obj!r} is not valid JSON (expected a finite number)")
        return float(obj)
    if isinstance(obj, os.PathLike):
        return os.fspath(obj)
    if isinstance(obj, Mapping):
        return {str(k): to_jsonable(v, f"{where}.{k}") for k, v in obj.items()}
    if type(obj).__module__.startswith("omegaconf"):
        from omegaconf import OmegaConf

        return to_jsonable(OmegaConf.to_container(obj, resolve=True), where)
    if type(obj).__module__ == "numpy":
        if hasattr(obj, "tolist"):
            return to_jsonable(obj.tolist(), where)
    if isinstance(obj, list | tuple):
        return [to_jsonable(v, f"{where}[{i}]") for i, v in enumerate(obj)]
    raise ValueError(f"{where}: cannot write {type(obj).__name__} to JSON")


def write_json(path: PathLike, obj: Any, *, indent: int | None = 2) -> Path:
    """Atomically write ``obj`` as JSON with sorted keys and a trailing newline.

    Deterministic bytes for equal input. numpy values are converted; NaN/inf raise
    ``ValueError`` naming the file and the key.
    """
    try:
        data = to_jsonable(obj)
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None
    text = json.dumps(data, indent=indent, sort_keys=True, allow_nan=False) + "\n"
    return write_text(path, text)


def write_yaml(path: PathLike, obj: Any) -> Path:
    """Atomically write ``obj`` (mapping/list, OmegaConf or plain) as YAML, keys in given order."""
    from omegaconf import OmegaConf

    text = OmegaConf.to_yaml(OmegaConf.create(to_jsonable(obj)))
    return write_text(path, text)


def write_parquet(path: PathLike, df: pd.DataFrame, *, index: bool = False, **kwargs: Any) -> Path:
    """Atomically write a DataFrame to Parquet (pyarrow); the index is dropped unless asked."""
    with atomic_path(path) as tmp:
        df.to_parquet(tmp, index=index, **kwargs)
    return Path(path)


def save_figure(fig: Figure, path: PathLike, **savefig_kwargs: Any) -> Path:
    """Atomically save a matplotlib figure; the format follows the suffix of ``path``.

    Timestamps are left out of SVG/PDF metadata so the same figure gives the same bytes.
    """
    suffix = Path(path).suffix.lower()
    if suffix in {".svg", ".pdf"}:
        savefig_kwargs.setdefault("metadata", {"Date": None} if suffix == ".svg" else {"CreationDate": None})
    with atomic_path(path) as tmp:
        fig.savefig(tmp, **savefig_kwargs)
    return Path(path)
