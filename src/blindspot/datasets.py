"""The outside data sets: where each comes from, how to get it, whether it is there.

The manifest (``blindspot/datasets.json``, committed) names, for every set, its public source
repository, the pinned commit, and each file's path in that repository, size (bytes) and sha256,
plus the set's licence file (kept with the set). The files land under the shared folder
(:func:`blindspot.config.shared_dir`: ``BLINDSPOT_SHARED``, else ``paths.shared_dir`` =
``../shared``) at ``<shared>/<target>/<path>``, which is where the stages read them.

Command line (:func:`main`)::

    python -m blindspot data list                    # the sets, their sources, who needs them
    python -m blindspot data fetch [SET ...]         # download at the pinned commits, check sha256
    python -m blindspot data fetch --from DIR        # copy from a local mirror laid out as <shared>
    python -m blindspot data fetch --to DIR          # write somewhere else than the shared folder
    python -m blindspot data check [SET ...]         # every file there, with its checksum?

Every file is checked against its sha256 before it is written (atomically, through
:mod:`blindspot.io`), so a fetch never leaves a wrong or half-written file under a good name.
Stages that need a set call :func:`require_paths` up front (through the stage runner,
:data:`STAGE_INPUTS`): a missing set raises :class:`DataMissing`, whose message names the set,
its source, where it was looked for and the command that gets it.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import sys
import urllib.parse
import urllib.request
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

from blindspot import io

__all__ = [
    "MANIFEST",
    "STAGE_INPUTS",
    "DataFile",
    "DataSet",
    "DataError",
    "DataMissing",
    "ChecksumMismatch",
    "load_manifest",
    "missing_files",
    "fetch",
    "require_paths",
    "stage_inputs",
    "main",
]

MANIFEST = Path(__file__).with_name("datasets.json")
FETCH_COMMAND = "python -m blindspot data fetch"

# Config keys of each stage that hold paths relative to the shared folder (``*`` = every entry
# of a mapping). The runner checks them before the stage starts (see stage_inputs).
STAGE_INPUTS: dict[str, tuple[str, ...]] = {
    "recordings": ("recordings.*.path",),
    "real_tracking": ("real_tracking.recordings.*.path",),
    "ethucy": ("ethucy.data",),
    "train_direct": ("direct.pretrain_data",),
}


class DataError(RuntimeError):
    """An outside data set is missing or wrong; the message says which and what to do."""


class DataMissing(DataError):
    """A file of an outside data set is not where the stages read it."""


class ChecksumMismatch(DataError):
    """A file's size or sha256 differs from the manifest."""


@dataclass(frozen=True)
class DataFile:
    path: str          # relative to the set's target folder
    source: str        # path in the source repository at the pinned commit
    size: int
    sha256: str
    licence: bool = False
    head_lines: int | None = None  # the file is the first N lines of `source`


@dataclass(frozen=True)
class DataSet:
    name: str
    title: str
    repository: str
    commit: str
    licence: str
    target: str        # folder relative to the shared folder
    used_by: tuple[str, ...]
    files: tuple[DataFile, ...]
    url_template: str
    note: str = ""

    @property
    def source(self) -> str:
        return f"https://github.com/{self.repository}/tree/{self.commit}"

    def url(self, f: DataFile) -> str:
        return self.url_template.format(repository=self.repository, commit=self.commit,
                                        source=urllib.parse.quote(f.source))

    @property
    def data_files(self) -> tuple[DataFile, ...]:
        return tuple(f for f in self.files if not f.licence)


@lru_cache(maxsize=4)
def _read_manifest(path: str) -> dict[str, Any]:
    return json.loads(Path(path).read_text(encoding="utf-8"))


def load_manifest(path: str | os.PathLike[str] = MANIFEST) -> dict[str, DataSet]:
    """The data sets of the manifest, by name (in manifest order)."""
    raw = _read_manifest(str(path))
    template = raw["url"]
    return {
        name: DataSet(name=name, title=s["title"], repository=s["repository"], commit=s["commit"],
                      licence=s["licence"], target=s["target"], used_by=tuple(s["used_by"]),
                      files=tuple(DataFile(**f) for f in s["files"]), url_template=template,
                      note=s.get("note", ""))
        for name, s in raw["sets"].items()
    }


def _select(sets: Mapping[str, DataSet], names: Sequence[str]) -> list[DataSet]:
    unknown = [n for n in names if n not in sets]
    if unknown:
        raise DataError(f"unknown data set(s) {', '.join(unknown)}; known: {', '.join(sets)}")
    return [sets[n] for n in names] if names else list(sets.values())


def _sha256_file(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _display(path: Path, base: Path | None = None) -> str:
    """``path`` relative to ``base`` (or the cwd) where it lies below it, else as given."""
    for b in (base, Path.cwd()):
        if b is not None:
            try:
                return str(path.resolve().relative_to(b.resolve()))
            except ValueError:
                pass
    return str(path)


def _how_to_get(ds: DataSet) -> str:
    return (f"get it with `{FETCH_COMMAND} {ds.name}` (downloads {ds.source}), or "
            f"`{FETCH_COMMAND} {ds.name} --from DIR` from a local mirror laid out like the "
            "shared folder; or point BLINDSPOT_SHARED at a folder that holds it")


def missing_files(ds: DataSet, shared: Path, *, checksums: bool = False,
                  licences: bool = False) -> list[str]:
    """Problems of set ``ds`` under ``shared``: one line per file absent, of the wrong size or,
    with ``checksums``, the wrong sha256. The data files; with ``licences``, the licence files."""
    problems = []
    for f in [f for f in ds.files if f.licence] if licences else ds.data_files:
        p = shared / ds.target / f.path
        if not p.is_file():
            problems.append(f"{ds.target}/{f.path}: absent")
        elif p.stat().st_size != f.size:
            problems.append(f"{ds.target}/{f.path}: {p.stat().st_size} bytes, expected {f.size}")
        elif checksums and _sha256_file(p) != f.sha256:
            problems.append(f"{ds.target}/{f.path}: sha256 differs from the manifest")
    return problems


def _read_source(ds: DataSet, f: DataFile, mirror: str | None) -> bytes:
    """The bytes of ``f``: from the mirror (a folder or file:// URL laid out as the shared
    folder) or from the source repository at the pinned commit."""
    if mirror is not None:
        base = mirror[len("file://"):] if mirror.startswith("file://") else mirror
        path = Path(base) / ds.target / f.path
        if not path.is_file():
            raise DataMissing(f"data set {ds.name}: {f.path} is not in the mirror {base} "
                              f"(looked for {ds.target}/{f.path}); {_how_to_get(ds)}")
        return path.read_bytes()
    url = ds.url(f)
    try:
        with urllib.request.urlopen(url, timeout=60) as resp:  # noqa: S310 (https or file)
            data: bytes = resp.read()
    except OSError as exc:
        raise DataMissing(f"data set {ds.name}: cannot download {url} ({exc}); source "
                          f"{ds.source}. Retry `{FETCH_COMMAND} {ds.name}`, or copy from a "
                          f"local mirror with `{FETCH_COMMAND} {ds.name} --from DIR`") from exc
    if f.head_lines is not None:
        data = b"".join(data.splitlines(keepends=True)[: f.head_lines])
    return data


def fetch(names: Sequence[str] = (), *, to: Path, mirror: str | None = None,
          manifest: str | os.PathLike[str] = MANIFEST,
          log: Any = print) -> list[Path]:
    """Get the sets ``names`` (all when empty) into ``to/<target>``; returns the files written.

    Files already there with the right sha256 are kept. Every file read is checked against the
    manifest before it is written atomically; a mismatch raises :class:`ChecksumMismatch` and
    leaves the file under its name as it was. From a mirror, a licence file the mirror lacks is
    reported and skipped (the data are still checked); from the source it is fetched too.
    """
    sets = load_manifest(manifest)
    written = []
    for ds in _select(sets, names):
        n_ok = 0
        for f in ds.files:
            dest = to / ds.target / f.path
            if dest.is_file() and dest.stat().st_size == f.size and _sha256_file(dest) == f.sha256:
                n_ok += 1
                continue
            try:
                data = _read_source(ds, f, mirror)
            except DataMissing:
                if f.licence and mirror is not None:
                    log(f"  {ds.name}: the mirror has no {f.path} (licence: {ds.licence}); "
                        f"`{FETCH_COMMAND} {ds.name}` without --from gets it from {ds.source}")
                    continue
                raise
            digest = hashlib.sha256(data).hexdigest()
            if len(data) != f.size or digest != f.sha256:
                where = mirror if mirror is not None else ds.url(f)
                raise ChecksumMismatch(
                    f"data set {ds.name}: {f.path} from {where} has {len(data)} bytes, sha256 "
                    f"{digest[:12]}..; the manifest pins {f.size} bytes, {f.sha256[:12]}.. "
                    f"({ds.repository} at {ds.commit}, {f.source}). Nothing was written; "
                    f"fetch it from the source with `{FETCH_COMMAND} {ds.name}`")
            written.append(io.write_bytes(dest, data))
        log(f"{ds.name}: {len(ds.files)} file(s) in {_display(to / ds.target)} "
            f"({n_ok} already there, {len(ds.files) - n_ok} fetched or skipped)")
    return written


def _config_values(cfg: Any, dotted: str) -> list[str]:
    """Values of the dotted key ``dotted`` in ``cfg`` (``*`` = every entry); absent -> []."""
    nodes = [cfg]
    for part in dotted.split("."):
        nxt = []
        for node in nodes:
            if node is None or not hasattr(node, "get"):
                continue
            if part == "*":
                nxt.extend(node[k] for k in node.keys())
            elif node.get(part) is not None:
                nxt.append(node.get(part))
        nodes = nxt
    return [str(v) for v in nodes]


def stage_inputs(stage: str, cfg: Any) -> list[str]:
    """The paths (relative to the shared folder, or absolute) stage ``stage`` reads from the
    shared folder under config ``cfg``; [] for a stage that needs no outside data."""
    return [v for key in STAGE_INPUTS.get(stage, ()) for v in _config_values(cfg, key)]


def require_paths(paths: Iterable[str], shared: Path, *, stage: str = "",
                  manifest: str | os.PathLike[str] = MANIFEST) -> None:
    """Raise :class:`DataMissing` unless every path (relative to ``shared``) is there.

    A path inside a set of the manifest requires that set's data files (present, right size);
    the message names the set, its source, the folder looked in and the command. A path outside
    every set (your own recording) must exist; an absolute path is checked as it is.
    """
    sets = load_manifest(manifest)
    who = f"stage {stage}: " if stage else ""
    for rel in paths:
        p = Path(rel)
        owner = next((ds for ds in sets.values()
                      if not p.is_absolute() and (p.as_posix() + "/").startswith(ds.target + "/")),
                     None)
        if owner is not None:
            problems = missing_files(owner, shared)
            if problems:
                shown = "; ".join(problems[:3]) + (f"; and {len(problems) - 3} more"
                                                   if len(problems) > 3 else "")
                raise DataMissing(
                    f"{who}needs the outside data set {owner.name!r} ({owner.title}; source "
                    f"{owner.source}), looked for in {shared / owner.target} "
                    f"(the shared folder: BLINDSPOT_SHARED, else paths.shared_dir): {shown}.\n"
                    f"  {_how_to_get(owner)}.")
            continue
        full = p if p.is_absolute() else shared / p
        if not full.exists():
            raise DataMissing(f"{who}reads {full}, which does not exist (not a file of the "
                              "outside data sets either: `python -m blindspot data list`)")


# --------------------------------------------------------------------------- command line

def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m blindspot data",
        description="The outside data sets the stages read: list them, fetch them at their "
                    "pinned commits (sha256 checked), check them. Manifest: "
                    "src/blindspot/datasets.json.")
    sub = p.add_subparsers(dest="command", required=True)
    sub.add_parser("list", help="the sets, their sources, licences and the stages that need them")
    f = sub.add_parser("fetch", help="download (or copy from a mirror) and check every file")
    f.add_argument("sets", nargs="*", metavar="SET", help="data sets (default: all)")
    f.add_argument("--from", dest="mirror", metavar="DIR",
                   help="copy from a local mirror laid out as the shared folder (a folder or "
                        "file:// URL) instead of downloading")
    f.add_argument("--to", metavar="DIR",
                   help="write there instead of the shared folder (BLINDSPOT_SHARED, else "
                        "paths.shared_dir)")
    c = sub.add_parser("check", help="every file present, with its size and sha256")
    c.add_argument("sets", nargs="*", metavar="SET", help="data sets (default: all)")
    c.add_argument("--in", dest="where", metavar="DIR", help="the folder to check (default: the "
                   "shared folder)")
    return p


def _default_shared() -> Path:
    from blindspot.config import ConfigNotFound, load_params, shared_dir

    try:
        return shared_dir(load_params())
    except (ConfigNotFound, FileNotFoundError):
        return shared_dir(None)


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m blindspot data ...``; returns the exit status (2 = data missing or wrong)."""
    args = _parser().parse_args(argv)
    sets = load_manifest()
    try:
        if args.command == "list":
            for ds in sets.values():
                size = sum(f.size for f in ds.files) / 1e6
                print(f"{ds.name:<19} {ds.title}\n{'':<19} {ds.repository} @ {ds.commit[:12]}, "
                      f"{len(ds.files)} files, {size:.1f} MB -> <shared>/{ds.target}\n"
                      f"{'':<19} licence: {ds.licence}; needed by stage(s): "
                      f"{', '.join(ds.used_by)}")
            print("Every other stage needs no outside data.")
            return 0
        if args.command == "fetch":
            to = Path(args.to) if args.to else _default_shared()
            fetch(args.sets, to=to, mirror=args.mirror)
            return 0
        where = Path(args.where) if args.where else _default_shared()
        bad = 0
        for ds in _select(sets, args.sets):
            problems = missing_files(ds, where, checksums=True)
            lic = missing_files(ds, where, checksums=True, licences=True)
            state = "ok" if not problems else f"{len(problems)} problem(s)"
            print(f"{ds.name}: {state}" + "".join(f"\n  {x}" for x in problems[:10])
                  + "".join(f"\n  licence file {x} (`{FETCH_COMMAND} {ds.name}` gets it)"
                            for x in lic))
            if problems:
                print(f"  {_how_to_get(ds)}")
            bad += bool(problems)
        return 2 if bad else 0
    except DataError as exc:
        print(f"[blindspot] {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(main())
