"""The stage protocol: what the runner hands a stage and what the stage hands back.

A stage (``stages/<name>.py``) is one function::

    def run(cfg: DictConfig, ctx: StageContext) -> StageResult:
        truth = pd.read_parquet(ctx.dep("truth.parquet"))        # a declared dep of the stage
        ...
        out = write_json(ctx.out("localise.json"), metrics)      # a declared out of the stage
        return StageResult(metrics=metrics, artifacts=[out])

The runner (:func:`blindspot.cli.run_stage`) is the one door to MLflow: it opens the stage's run,
calls ``run(cfg, ctx)`` and logs the returned :class:`StageResult` (metrics, artifacts, model
files, tags). Stages and the library never import :mod:`blindspot.runs`.

Live metrics (per training epoch) are the one thing that cannot wait for the result: the runner
hands the stage ``ctx.log_step(metrics, step)``, a plain callable bound to the run's tracker
(a no-op when tracking is off), which the stage passes on to the library as a callback (e.g.
``train_lstm(..., on_epoch=ctx.log_step)``). It is a parameter, not a global "current run": the
dependency is visible in the stage's signature, the library sees only a callable, and a test can
hand in a context whose ``log_step`` records into a list.

Every file a stage reads from or writes for another stage is declared once, in ``dvc.yaml``: the
stage names it (``ctx.dep("truth.parquet")``, ``ctx.out("detections.parquet")``, by its file name
or any trailing part of its path) and gets the declared path; a name that is not declared, or
ambiguous, raises :class:`UndeclaredPath` naming the stage, the name and what is declared. Under
DVC (:func:`blindspot.cli.main_stage`) the runner also checks after the stage that it asked for
every declared out (see :meth:`StageContext.check_outs`), so what a stage writes is exactly what
``dvc.yaml`` declares.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

__all__ = [
    "DVC_FILE",
    "StageResult",
    "StageContext",
    "StepLogger",
    "DeclaredFiles",
    "UndeclaredPath",
    "MissingInput",
    "declared_files",
    "missing_inputs",
]

DVC_FILE = "dvc.yaml"

PathLike = str | os.PathLike[str]
StepLogger = Callable[[Mapping[str, Any], int], None]
"""``log_step(metrics, step)``: numeric metrics (nested mappings -> dotted names) at ``step``."""


@dataclass(frozen=True)
class StageResult:
    """What a stage returns; the runner logs it to the stage's MLflow run.

    metrics     : numbers by name; nested mappings become dotted names (``{"val": {"rmse_m": x}}``
                  -> ``val.rmse_m``). Logged once, at step 0.
    artifacts   : files or folders copied to the run's artifacts (its root).
    model_files : saved models (checkpoint files or folders), logged under ``model/``.
    tags        : run tags (values are turned into strings).
    """

    metrics: Mapping[str, Any] = field(default_factory=dict)
    artifacts: Sequence[PathLike] = ()
    model_files: Sequence[PathLike] = ()
    tags: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        for name in ("artifacts", "model_files"):
            value = getattr(self, name)
            if isinstance(value, str | os.PathLike):
                raise TypeError(f"StageResult.{name}: expected a sequence of paths, found the "
                                f"single path {value!r}; wrap it in a list")


class UndeclaredPath(LookupError):
    """A stage asked for a file its ``dvc.yaml`` entry does not declare (or declares twice)."""


class MissingInput(FileNotFoundError):
    """A stage was run before the files it reads exist: the message names each missing file,
    the stage of ``dvc.yaml`` that makes it and the command to run (:func:`missing_inputs`)."""


@dataclass(frozen=True)
class DeclaredFiles:
    """The deps and outs (outs, metrics and plots) of one stage in ``dvc.yaml``, as written there
    (paths relative to the repository root)."""

    stage: str
    deps: tuple[str, ...]
    outs: tuple[str, ...]


def _entry_paths(entries: Any) -> tuple[str, ...]:
    """Paths of a dvc.yaml list whose items are ``path`` or ``{path: {options}}``."""
    paths = []
    for item in entries or ():
        if isinstance(item, Mapping):
            paths.extend(str(k) for k in item)
        else:
            paths.append(str(item))
    return tuple(paths)


def read_dvc_stages(repo_root: PathLike) -> dict[str, DeclaredFiles]:
    """Every stage of ``<repo_root>/dvc.yaml`` by name ({} when there is no dvc.yaml)."""
    import yaml

    path = Path(repo_root) / DVC_FILE
    if not path.is_file():
        return {}
    # libyaml's safe loader where installed (same result as yaml.safe_load, ~10x faster on the
    # 900-line dvc.yaml every stage reads)
    loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
    stages = (yaml.load(path.read_text(), Loader=loader) or {}).get("stages") or {}
    return {
        name: DeclaredFiles(
            name,
            _entry_paths(spec.get("deps")),
            _entry_paths(spec.get("outs")) + _entry_paths(spec.get("metrics"))
            + _entry_paths(spec.get("plots")),
        )
        for name, spec in stages.items()
    }


def declared_files(repo_root: PathLike, stage: str) -> DeclaredFiles:
    """The declared deps and outs of ``stage``; none when ``dvc.yaml`` has no such stage."""
    return read_dvc_stages(repo_root).get(stage) or DeclaredFiles(stage, (), ())


def _producer(dep: str, stages: Mapping[str, DeclaredFiles]) -> str | None:
    """The stage whose declared out is ``dep``, holds it (a folder out) or lies in it."""
    dep = dep.strip("/")
    for name, files in stages.items():
        for out in files.outs:
            out = out.strip("/")
            if dep == out or dep.startswith(out + "/") or out.startswith(dep + "/"):
                return name
    return None


def missing_inputs(repo_root: PathLike, stage: str) -> None:
    """Raise :class:`MissingInput` unless every dep ``dvc.yaml`` declares for ``stage`` exists
    under ``repo_root``; the message names each missing file, the stage that makes it (from
    the outs of ``dvc.yaml``) and the commands that make it: ``dvc repro <stage>`` (the
    upstream stages, then this one) or ``python -m blindspot <producer>``. A stage ``dvc.yaml``
    does not know passes."""
    stages = read_dvc_stages(repo_root)
    files = stages.get(stage)
    if files is None:
        return
    root = Path(repo_root)
    missing = [d for d in files.deps if not (root / d).exists()]
    if not missing:
        return
    lines = []
    producers: list[str] = []
    for dep in missing:
        maker = _producer(dep, stages)
        if maker is None:
            lines.append(f"  {dep}: no stage of {DVC_FILE} makes it (an input of the project: "
                         "check the path)")
        else:
            lines.append(f"  {dep}: made by stage {maker!r} (python -m blindspot {maker})")
            if maker not in producers:
                producers.append(maker)
    fix = (f"Run `dvc repro {stage}` (it makes the missing inputs first, then runs this "
           "stage)" + (", or run the stages named above first" if producers else "") + ".")
    raise MissingInput(f"stage {stage!r} cannot run: {len(missing)} of its inputs declared in "
                       f"{DVC_FILE} do not exist:\n" + "\n".join(lines) + "\n" + fix)


def _match(key: str, paths: Sequence[str]) -> list[str]:
    """The declared paths that are ``key`` or end with ``/key``; a path equal to ``key`` wins
    (``README.md`` is the repository's README even when ``reports/README.md`` is declared too)."""
    key = key.strip("/")
    exact = [p for p in paths if p == key]
    return exact or [p for p in paths if p.endswith("/" + key)]


class StageContext:
    """What the runner hands a stage: its declared files and the live metric logger.

    ``files`` : the stage's :class:`DeclaredFiles`; ``log_step`` : a :data:`StepLogger` bound to
    the stage's MLflow run. Paths are relative to the repository root (the stage's cwd).

    ``out_root`` : None for a pipeline run (outs are the declared paths, what DVC tracks); for
    one job of a Hydra multirun sweep, the job's own output directory: every out is then
    ``out_root / <declared path>``, so sweep jobs never write over the pipeline's outputs nor
    over each other's (deps are still read from the repository).
    """

    def __init__(self, files: DeclaredFiles, log_step: StepLogger | None = None,
                 out_root: PathLike | None = None):
        self.files = files
        self.name = files.stage
        self._log_step = log_step
        self.out_root = None if out_root is None else Path(out_root)
        self.requested_outs: set[str] = set()

    def out_path(self, declared: str) -> Path:
        """Where the declared out ``declared`` is written by this run (see ``out_root``)."""
        return Path(declared) if self.out_root is None else self.out_root / declared

    def log_step(self, metrics: Mapping[str, Any], step: int) -> None:
        """Log ``metrics`` at ``step`` to the stage's run now (e.g. once per training epoch)."""
        if self._log_step is not None:
            self._log_step(metrics, step)

    def _lookup(self, key: str, kind: str, paths: Sequence[str]) -> str:
        found = _match(key, paths)
        if len(found) == 1:
            return found[0]
        what = "declares no" if not found else f"declares {len(found)} matching"
        raise UndeclaredPath(
            f"stage {self.name!r}: {DVC_FILE} {what} {kind} {key!r} ({found or 'none'}); its "
            f"{kind}s there: {', '.join(paths) or '(none)'}. Declare each file once, in "
            f"{DVC_FILE}, and name it by its file name or a trailing part of its path")

    def dep(self, key: str) -> Path:
        """The declared dep whose path is ``key`` or ends with ``/key``."""
        return Path(self._lookup(key, "dep", self.files.deps))

    def out(self, key: str) -> Path:
        """The declared out (outs, metrics or plots) whose path is ``key`` or ends with ``/key``;
        under ``out_root`` (a sweep job's directory, its parent folders created) when set."""
        path = self._lookup(key, "out", self.files.outs)
        self.requested_outs.add(path)
        target = self.out_path(path)
        if self.out_root is not None:
            target.parent.mkdir(parents=True, exist_ok=True)
        return target

    def check_outs(self) -> None:
        """Raise :class:`UndeclaredPath` unless the stage asked for every declared out, each of
        which now exists (what the stage wrote is what dvc.yaml declares)."""
        never = [p for p in self.files.outs if p not in self.requested_outs]
        missing = [p for p in self.files.outs
                   if p in self.requested_outs and not self.out_path(p).exists()]
        if never or missing:
            raise UndeclaredPath(
                f"stage {self.name!r}: {DVC_FILE} declares outs the stage did not write: "
                + "; ".join(filter(None, [
                    f"never asked for {', '.join(never)}" if never else "",
                    f"asked for but missing {', '.join(missing)}" if missing else ""]))
                + f". Write each through ctx.out(...) or remove it from {DVC_FILE}")
