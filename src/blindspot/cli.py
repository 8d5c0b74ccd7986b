"""Command line: run pipeline stages, sweeps and the params.yaml tools.

How to run things (from anywhere inside the repository)::

    dvc repro                                   # the pipeline; stages read params.yaml
    dvc exp run -S 'train.lr=0.01'              # DVC composes conf/ + override into params.yaml
    dvc exp run --queue -S 'model.hidden_size=32,64' && dvc queue start -j 2

    python -m blindspot <stage> key=value ...   # one stage outside DVC: conf/ + overrides;
                                                # differing from params.yaml, its outputs go to
                                                # its own outputs/<date>/<time>/ (not over DVC's)
    python -m blindspot train -m model.hidden_size=32,64,128           # Hydra multirun sweep
    python -m blindspot train -m hydra/launcher=parallel model.hidden_size=32,64   # 2 processes
    python -m blindspot train -m +search=lstm   # Optuna search (conf/search/lstm.yaml)
    python -m blindspot train -m hydra/launcher=submitit|slurm|ray_cluster ...   # [cluster] extra
    python -m blindspot <stage> --cfg job       # print the composed config, run nothing
    python -m blindspot <stage> --help          # the config keys the stage reads, its data sets
    python -m blindspot --help                  # every stage in one line, and the commands

    python -m blindspot params                  # regenerate params.yaml from conf/
    python -m blindspot check-params            # fail (exit 1) if params.yaml != conf/
    python -m blindspot stages                  # list the stages
    python -m blindspot cleanup                 # after a SIGKILL: close its run, remove its temps
    python -m blindspot data list|fetch|check   # the outside data sets (blindspot.datasets)

``blindspot`` (the console script) is the same as ``python -m blindspot``. A stage whose config
names files of an outside data set (:data:`blindspot.datasets.STAGE_INPUTS`) checks that they
are there before its run starts, and stops with exit 2 naming the set and the command if not.

Every stage run is one MLflow run (params = the keys its dvc.yaml stage lists, metrics,
artifacts); a sweep is a parent run (``train-optuna-<study>``, ``train-submitit-<time>``) with
one nested child run per job. The store is ``<repo>/mlflow.db`` (SQLite, absolute path; also for
``dvc queue`` runs, which execute in temporary copies). Open the UI from the repo root and
compare runs there; the view opens on the headline metrics and the changed params::

    mlflow ui --backend-store-uri sqlite:///$PWD/mlflow.db
    # http://127.0.0.1:5000/#/experiments/1/runs?viewStateShareKey=headline&workflowType=machine_learning

Stage convention (:mod:`blindspot.stage`): ``stages/<name>.py`` defines
``run(cfg: DictConfig, ctx: StageContext) -> StageResult`` and ends with::

    if __name__ == "__main__":
        blindspot.cli.main_stage(run, "<name>")

Under DVC (``python stages/<name>.py``) the config is ``params.yaml`` (what DVC tracked),
checked against ``conf/`` unless DVC composed it itself (``dvc exp run``), and the stage must
write every out ``dvc.yaml`` declares for it. With ``python -m blindspot <name> ...`` it is
``conf/`` + the overrides, composed by Hydra. Both call the same ``run(cfg, ctx)`` inside
:func:`blindspot.runs.stage_run`, with the working directory set to the repo root, and log
the :class:`~blindspot.stage.StageResult` it returns: this runner is the one door to MLflow.
"""

from __future__ import annotations

import hashlib
import importlib.metadata
import importlib.util
import os
import re
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from types import ModuleType

from dataclasses import dataclass
from typing import ClassVar

from omegaconf import DictConfig, OmegaConf

from blindspot import config as bconfig
from blindspot import datasets, io, kernels, runs
from blindspot.stage import (MissingInput, StageContext, StageResult, declared_files,
                             missing_inputs, read_dvc_stages)
from blindspot.typed_config import TypedConfig, setting

__all__ = [
    "StageFunction",
    "UnknownStage",
    "available_stages",
    "load_stage",
    "run_stage",
    "sweep_job_dir",
    "single_run_dir",
    "SearchConfig",
    "objective_value",
    "log_result",
    "main_stage",
    "main",
    "STAMP_FILE",
    "params_fingerprint",
    "check_params_stamped",
]

StageFunction = Callable[[DictConfig, StageContext], StageResult]

COMMANDS = {
    "params": "regenerate params.yaml from conf/",
    "check-params": "fail if params.yaml is not what conf/ composes to",
    "stages": "list the stages",
    "cleanup": "end KILLED the runs of processes gone (SIGKILL); remove their temporary files",
    "data": "the outside data sets: list, fetch (pinned commits, sha256 checked), check",
}

# Hydra flags that take a value (moved in front of the overrides together with their value).
_VALUE_FLAGS = {"--cfg", "-c", "--package", "-p", "--config-path", "-cp", "--config-name",
                "-cn", "--config-dir", "-cd", "--experimental-rerun", "--shell-completion", "-sc"}
_INFO_FLAGS = {"--info", "-i"}
_INFO_VALUES = {"all", "config", "defaults", "defaults-tree", "plugins", "searchpath"}
# Hydra flags with which no stage runs (print the config, help, completion): inputs not needed
_NO_RUN_FLAGS = {"--cfg", "-c", "--info", "-i", "--help", "-h", "--hydra-help",
                 "--shell-completion", "-sc", "--resolve"}


# Where a passing params check leaves its stamp: DVC's own scratch folder (git-ignored by
# .dvc/.gitignore), so only DVC repositories have one. See check_params_stamped.
STAMP_FILE = Path(".dvc", "tmp", "blindspot-params-check")
_STAMP_FORMAT = b"blindspot params check, stamp format 1\n"
# ${oc.env:NAME}, and OmegaConf's other spellings: blanks around the colon, a quoted name
_OC_ENV = re.compile(rb"\$\{\s*oc\.env\s*:\s*['\"]?([A-Za-z_][A-Za-z0-9_]*)")


def params_fingerprint(repo_root: str | os.PathLike[str]) -> str:
    """SHA-256 (hex) of everything the verdict of :func:`blindspot.config.check_params` depends on.

    That is: the bytes of ``params.yaml`` and of every file under ``conf/`` (with its path), the
    values of the environment variables ``conf/`` reads through ``${oc.env:NAME}`` (the whole
    environment when a file uses ``oc.env`` in a form whose name cannot be read, e.g. nested
    interpolation: conservative, such a stamp rarely matches and the check composes), and the
    code that composes and compares (:mod:`blindspot.config`, Hydra's and OmegaConf's installed
    versions and package ``__init__`` files). Folders under ``conf/`` are walked through
    symbolic links. Equal fingerprints mean the composition of
    ``conf/`` and its comparison with params.yaml would give the same answer. Reads files only
    (milliseconds; no Hydra import). Raises ``FileNotFoundError`` when params.yaml is absent.
    """
    root = Path(repo_root).resolve()
    digest = hashlib.sha256(_STAMP_FORMAT)

    def add(label: str, data: bytes) -> None:
        digest.update(f"{label}\0{len(data)}\0".encode())
        digest.update(data)

    add(bconfig.PARAMS_FILE, (root / bconfig.PARAMS_FILE).read_bytes())
    conf_dir = root / bconfig.CONFIG_DIR
    env_names: set[str] = set()
    whole_env = False
    files = _conf_files(conf_dir)
    for path in files:
        data = path.read_bytes()
        add(path.relative_to(conf_dir).as_posix(), data)
        found = _OC_ENV.findall(data)
        env_names.update(m.decode() for m in found)
        whole_env |= data.count(b"oc.env") > len(found)
    if whole_env:
        env_names.update(os.environ)
    for name in sorted(env_names):
        value = os.environ.get(name)
        add(f"env:{name}", b"\1" if value is None else b"\2" + value.encode())
    add("code:blindspot.config", Path(bconfig.__file__).read_bytes())
    for package, dist in (("hydra", "hydra-core"), ("omegaconf", "omegaconf")):
        spec = importlib.util.find_spec(package)
        origin = spec.origin if spec is not None else None
        add(f"code:{package}", Path(origin).read_bytes() if origin else b"")
        try:
            add(f"version:{dist}", importlib.metadata.version(dist).encode())
        except importlib.metadata.PackageNotFoundError:
            add(f"version:{dist}", b"")
    return digest.hexdigest()


def _conf_files(conf_dir: Path) -> list[Path]:
    """Every regular file under ``conf_dir``, sorted, walking symlinked folders once each
    (a link to a folder already walked, e.g. a parent, is skipped) and leaving out broken
    links (an editor's lock file such as Emacs's ``.#config.yaml``)."""
    seen: set[str] = set()
    out = []
    for folder, subs, names in os.walk(conf_dir, followlinks=True):
        seen.add(os.path.realpath(folder))
        subs[:] = [d for d in subs if os.path.realpath(os.path.join(folder, d)) not in seen]
        out.extend(Path(folder, f) for f in names if os.path.isfile(os.path.join(folder, f)))
    return sorted(out)


def _read_stamp(path: Path) -> str | None:
    try:
        return path.read_text(encoding="ascii").strip()
    except (OSError, UnicodeDecodeError):
        return None


def _write_stamp(path: Path, fingerprint: str) -> None:
    """Write the stamp by temporary file and rename (a killed writer leaves no half stamp).
    Not through blindspot.io's writers: those are fault points, and a stamp is written only by
    the first check after an edit, so it would shift a stage's fault-point numbering between
    runs (tests/faults)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f"{path.name}.{os.getpid()}.tmp")
    try:
        tmp.write_text(fingerprint + "\n", encoding="ascii")
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def check_params_stamped(repo_root: str | os.PathLike[str], *, stamp: bool = True) -> None:
    """:func:`blindspot.config.check_params` (raises ``ParamsOutOfDate``), skipped while nothing
    it depends on changed since it last passed.

    Composing ``conf/`` with Hydra costs about a second of CPU, and every DVC stage checks before
    it runs. So a check that passes leaves a stamp, ``.dvc/tmp/blindspot-params-check`` (only in
    a repository that has ``.dvc/``), holding :func:`params_fingerprint`; with ``stamp`` True a
    later check whose fingerprint equals the stamp passes without composing. Any edit of
    ``conf/`` or params.yaml (by hand, by ``dvc exp run``, by git), a change of a variable
    ``conf/`` reads with ``oc.env`` or of the composing code changes the fingerprint, and the
    full comparison runs again. A failing check removes the stamp. ``stamp=False`` always
    composes (``python -m blindspot check-params`` does; it refreshes the stamp).
    """
    root = Path(repo_root).resolve()
    params = root / bconfig.PARAMS_FILE
    stamp_path = root / STAMP_FILE if (root / ".dvc").is_dir() else None
    fingerprint = params_fingerprint(root) if params.is_file() and stamp_path else None
    if stamp and fingerprint is not None and _read_stamp(stamp_path) == fingerprint:
        return
    try:
        bconfig.check_params(root)
    except BaseException:
        if stamp_path is not None:
            stamp_path.unlink(missing_ok=True)
        raise
    # stamp only what was compared: files edited while Hydra composed change the fingerprint
    if fingerprint is not None and params_fingerprint(root) == fingerprint:
        _write_stamp(stamp_path, fingerprint)


class UnknownStage(LookupError):
    """The stage named on the command line has no stages/<name>.py."""


def available_stages(repo_root: str | os.PathLike[str]) -> list[str]:
    """Names of ``<repo>/stages/*.py`` (without ``_``-prefixed helpers), sorted."""
    folder = Path(repo_root) / "stages"
    return sorted(p.stem for p in folder.glob("*.py") if not p.stem.startswith("_"))


_LOADED: dict[Path, ModuleType] = {}


def load_stage(repo_root: str | os.PathLike[str], name: str) -> StageFunction:
    """Import ``<repo>/stages/<name>.py`` by path and return its ``run`` function.

    Raises :class:`UnknownStage` listing the stages that exist, or ``TypeError`` if the file
    has no callable ``run``.
    """
    path = (Path(repo_root) / "stages" / f"{name}.py").resolve()
    if not path.is_file():
        known = available_stages(repo_root)
        raise UnknownStage(
            f"unknown stage {name!r}: no {path}. Stages: {', '.join(known) or '(none)'}; "
            f"commands: {', '.join(COMMANDS)}"
        )
    module = _LOADED.get(path)
    if module is None:
        spec = importlib.util.spec_from_file_location(f"blindspot_stage_{name}", path)
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        _LOADED[path] = module
    run = getattr(module, "run", None)
    if not callable(run):
        raise TypeError(f"{path} must define `def run(cfg: DictConfig, ctx: StageContext) -> "
                        "StageResult`")
    return run  # type: ignore[no-any-return]


def run_stage(
    run: StageFunction,
    name: str,
    cfg: DictConfig,
    repo_root: str | os.PathLike[str] | None = None,
    *,
    check_outs: bool = False,
    out_root: str | os.PathLike[str] | None = None,
) -> StageResult:
    """Call ``run(cfg, ctx)`` inside ``runs.stage_run(name, cfg)`` from the repo root and log
    the :class:`StageResult` it returns (metrics, artifacts, model files, tags) to that run.

    Temporary files a SIGKILLed earlier run left next to the stage's outs are removed first
    (:func:`blindspot.io.remove_stale_temps`). The stage runs inside
    :func:`blindspot.io.all_or_none`: its outputs appear together when it returns, and none
    of them changes when it raises. ``cfg`` is resolved and put in struct mode (a misspelt key raises instead of reading None).
    ``ctx`` carries the stage's files declared in ``dvc.yaml`` and ``ctx.log_step``, bound to the
    run. ``check_outs``: afterwards, require that the stage wrote every declared out
    (:meth:`StageContext.check_outs`). Raises ``TypeError`` if ``run`` returns something else
    than a :class:`StageResult`. ``out_root``: write the stage's outs under this folder (a sweep
    job's output directory, see :func:`sweep_job_dir`) instead of over the pipeline's own.
    """
    root = Path(repo_root).resolve() if repo_root is not None else bconfig.find_repo_root()
    os.chdir(root)
    cfg = OmegaConf.create(OmegaConf.to_container(cfg, resolve=True))
    OmegaConf.set_struct(cfg, True)
    # outside data first: a missing set is a message (DataMissing), not a failed run
    datasets.require_paths(datasets.stage_inputs(name, cfg), bconfig.shared_dir(cfg), stage=name)
    files = declared_files(root, name)
    runs.children_die_with_this_process()  # a SIGKILLed stage's pool workers die with it
    out_dir = None if out_root is None else Path(out_root).resolve()
    outs = files.outs if out_dir is None else [out_dir / o for o in files.outs]
    for debris in io.remove_stale_temps(outs):  # left by a SIGKILLed run of the stage
        print(f"[blindspot] stage {name}: removed {debris}, a killed writer's temporary file",
              file=sys.stderr)
    with runs.stage_run(name, cfg, repo_root=root) as tracker:
        if out_dir is not None:
            tracker.set_tags({"blindspot.out_root": str(out_dir)})
        ctx = StageContext(files, log_step=lambda metrics, step: tracker.log_metrics(metrics, step),
                           out_root=out_dir)
        # all of the stage's outputs land together when it returns, or none does when it fails
        # (several recordings, scenes or figures: never the first ones' new files beside the
        # others' old ones); a resume checkpoint is written at once (io.write_now)
        with io.all_or_none():
            result = run(cfg, ctx)
        if not isinstance(result, StageResult):
            raise TypeError(f"stage {name!r}: run(cfg, ctx) returned {type(result).__name__}; "
                            "expected a blindspot.stage.StageResult")
        log_result(tracker, result)
        if check_outs:
            ctx.check_outs()
    return result


def log_result(tracker: runs.NullTracker, result: StageResult) -> None:
    """Log a stage's result into its run: metrics, artifacts (run root), model files
    (``model/``), tags."""
    if result.metrics:
        tracker.log_metrics(result.metrics)
    for path in result.artifacts:
        tracker.log_artifact(path)
    for path in result.model_files:
        tracker.log_model_file(path)
    if result.tags:
        tracker.set_tags(result.tags)


def main_stage(run: StageFunction, name: str, argv: Sequence[str] | None = None) -> None:
    """Entry point of ``python stages/<name>.py`` (what dvc.yaml calls): config = params.yaml.

    Outside ``dvc exp run`` (env ``DVC_EXP_NAME`` unset) params.yaml is first checked against
    conf/ (:func:`check_params_stamped`: skipped while the stamp of the last passing check
    matches conf/ and params.yaml); if stale the process exits 1 with the fix. Takes no arguments (exit 2 says how to
    override). The stage must write every out dvc.yaml declares for it (else
    :class:`~blindspot.stage.UndeclaredPath`). SIGTERM ends the MLflow run KILLED and exits 143.
    """
    args = list(sys.argv[1:] if argv is None else argv)
    if args:
        print(
            f"stages/{name}.py takes no arguments: it reads params.yaml (what DVC tracks).\n"
            f"To override values: `python -m blindspot {name} {' '.join(args)}` (outside DVC) "
            f"or `dvc exp run -S '<key>=<value>'`.",
            file=sys.stderr,
        )
        raise SystemExit(2)
    if kernels.needs_reexec():
        # numpy/torch were imported before blindspot pinned their kernels (see blindspot.kernels):
        # start again with the pins in the environment, so the outputs match the committed lock
        sys.stdout.flush()
        sys.stderr.flush()
        os.environ[kernels.REEXEC_ENV] = "1"
        os.execv(sys.executable, [sys.executable, *sys.orig_argv[1:]])
    stage_file = Path(getattr(run, "__code__").co_filename)
    try:
        root = bconfig.find_repo_root(stage_file.parent)
    except bconfig.ConfigNotFound:
        root = bconfig.find_repo_root()
    try:
        if not os.environ.get("DVC_EXP_NAME"):
            check_params_stamped(root)  # composes conf/ only after an edit
        cfg = bconfig.load_params(root)
        missing_inputs(root, name)      # MissingInput (a FileNotFoundError): what makes them
    except Exception as exc:  # noqa: BLE001 - the config errors below; anything else re-raised
        # Hydra is imported only when conf/ is composed, so only then can its errors occur
        hydra_errors = sys.modules.get("hydra.errors")
        if not isinstance(exc, (bconfig.ParamsOutOfDate, FileNotFoundError)) and not (
                hydra_errors is not None and isinstance(exc, hydra_errors.HydraException)):
            raise
        print(f"[blindspot] {exc}" if isinstance(exc, MissingInput)
              else f"[blindspot] stage {name}: {exc}", file=sys.stderr)
        raise SystemExit(1) from None
    try:
        run_stage(run, name, cfg, root, check_outs=True)
    except datasets.DataMissing as exc:
        print(f"[blindspot] {exc}", file=sys.stderr)
        raise SystemExit(2) from None


class _StageTask:
    """Hydra task function for one stage; picklable by reference (for joblib/loky workers)."""

    def __init__(self, repo_root: str, name: str):
        self.repo_root = repo_root
        self.name = name

    def __call__(self, cfg: DictConfig) -> float | None:
        search = SearchConfig.from_mapping(cfg.search) if cfg.get("search") is not None else None
        out_root = sweep_job_dir()
        if out_root is None:
            out_root = single_run_dir(cfg, self.repo_root, self.name)
        try:
            result = run_stage(load_stage(self.repo_root, self.name), self.name, cfg,
                               self.repo_root, out_root=out_root)
        except datasets.DataMissing as exc:  # SystemExit passes Hydra's traceback printer
            print(f"[blindspot] {exc}", file=sys.stderr)
            raise SystemExit(2) from None
        return None if search is None else objective_value(result, search.objective, self.name)


@dataclass(frozen=True)
class SearchConfig(TypedConfig):
    """``cfg.search`` (``conf/search/*.yaml``, given as ``+search=<name>``): what each job of a
    hyper-parameter search (Hydra's Optuna sweeper) returns to the sweeper.

    objective: dotted name of a metric of the swept stage's :class:`StageResult` (e.g.
        ``lstm.val.rmse_m`` of ``train``); the job returns its value, which the sweeper's
        ``direction`` minimises or maximises.
    """

    GROUP: ClassVar[str] = "search"
    objective: str = setting(doc="dotted metric name of the stage's result")


def objective_value(result: StageResult, objective: str, stage: str) -> float:
    """The metric ``objective`` (dotted name) of ``result``; ``KeyError`` naming the config key
    ``search.objective``, the stage and the metrics it has, when it has no such metric."""
    from blindspot.config import flatten

    metrics = flatten(dict(result.metrics))
    if objective not in metrics:
        raise KeyError(f"config key 'search.objective' is {objective!r}, but stage {stage!r} "
                       f"returns no such metric; it has: {', '.join(sorted(metrics)) or '(none)'}")
    return float(metrics[objective])


def sweep_job_dir() -> Path | None:
    """The output directory of the Hydra job this process runs, when it is one job of a
    multirun sweep (``-m``; any launcher or sweeper); None for a single run.

    A sweep's jobs write their stage outs there (``<sweep dir>/<job num>/data/train/model.pt``
    ...), never over the DVC-tracked outputs of the pipeline, which a sweep of N jobs would
    otherwise overwrite N times (at once, on a parallel launcher). Their comparison lives in
    MLflow (one child run per job) and in the sweep's ``sweep_summary.csv``.
    """
    from hydra.core.hydra_config import HydraConfig

    if not HydraConfig.initialized():
        return None
    hc = HydraConfig.get()
    if hc.mode is None or hc.mode.name != "MULTIRUN" or not hc.runtime.output_dir:
        return None
    # A relative hydra.sweep.dir is taken from the cwd of the process that launched the sweep
    # (hydra.runtime.cwd), not from the job's: a Ray worker runs in a folder of Ray's own.
    return Path(hc.runtime.cwd, hc.sweep.dir, hc.sweep.subdir).resolve()


# Keys whose values never change what a stage writes: a run that differs only in them still
# writes the pipeline's outputs.
_OUTPUT_NEUTRAL = ("runs", "progress")


def single_run_dir(cfg: DictConfig, repo_root: str | os.PathLike[str], name: str) -> Path | None:
    """Where a single run (``python -m blindspot <stage> key=value``, not a sweep) writes its
    outs: None (the pipeline's own, DVC-tracked paths) when its config equals params.yaml but
    for :data:`_OUTPUT_NEUTRAL` keys; otherwise the run's own Hydra output directory
    (``outputs/<date>/<time>``, git-ignored), like a sweep job's, so that a run with overrides
    never writes over what DVC tracks. Without params.yaml, any override counts as a change.
    Says which keys differ and the ``dvc exp run -S`` command that runs them in the pipeline."""
    from hydra.core.hydra_config import HydraConfig

    if not HydraConfig.initialized():
        return None
    hc = HydraConfig.get()
    task = {k: v for k, v in OmegaConf.to_container(cfg, resolve=True).items()
            if k not in ("hydra", *_OUTPUT_NEUTRAL)}
    params_file = Path(repo_root) / bconfig.PARAMS_FILE
    if params_file.is_file():
        params = {k: v for k, v in OmegaConf.to_container(
            bconfig.load_params(repo_root), resolve=True).items() if k not in _OUTPUT_NEUTRAL}
        changed = [d.key for d in bconfig.params_diff(task, params)]
    else:
        changed = [o.partition("=")[0].lstrip("+~") for o in hc.overrides.task
                   if o.partition("=")[0].lstrip("+~").split(".")[0] not in _OUTPUT_NEUTRAL]
    if not changed or not hc.runtime.output_dir:
        return None
    out = Path(hc.runtime.output_dir).resolve()
    flat = bconfig.flatten(task)
    sets = " ".join(f"-S '{k}={_override_text(flat[k])}'" for k in changed if k in flat)
    if out == Path(repo_root).resolve():  # hydra.run.dir=. : the run folder is the pipeline's
        raise SystemExit(f"[blindspot] {name}: this config differs from params.yaml in "
                         f"{', '.join(changed[:8])}, and hydra.run.dir is the repository root, "
                         "so its outputs would overwrite the pipeline's. Run it in the pipeline "
                         f"with `dvc exp run {sets}`, or leave hydra.run.dir alone")
    print(f"[blindspot] {name}: this config differs from params.yaml in "
          f"{', '.join(changed[:8])}{' ...' if len(changed) > 8 else ''}; its outputs go to "
          f"{out}, not over the pipeline's (DVC-tracked) ones. To run it in the pipeline: "
          f"dvc exp run {sets}", file=sys.stderr)
    return out


def _override_text(value: object) -> str:
    import json

    if isinstance(value, bool) or value is None or isinstance(value, list | dict):
        return json.dumps(value)
    return str(value)


def _hydra_argv(args: Sequence[str], name: str) -> list[str]:
    """Hydra flags first, then the user's overrides, then ours (argparse needs that order)."""
    flags: list[str] = []
    overrides: list[str] = []
    i = 0
    while i < len(args):
        arg = args[i]
        if arg.startswith("-"):
            flags.append(arg)
            takes_value = arg in _VALUE_FLAGS or (
                arg in _INFO_FLAGS and i + 1 < len(args) and args[i + 1] in _INFO_VALUES
            )
            if takes_value and i + 1 < len(args):
                flags.append(args[i + 1])
                i += 1
            elif arg in _INFO_FLAGS:
                flags.append("all")  # bare --info: Hydra's default, said so argparse does not
                # take the overrides that follow as its value
        else:
            overrides.append(arg)
        i += 1
    bconfig.check_renamed_keys(overrides, f"python -m blindspot {name}")
    ours = [
        f"hydra.job.name={name}",
        "++hydra.callbacks.blindspot_tracking._target_=blindspot.runs.SweepCallback",
    ]
    return [*flags, *overrides, *ours]


def _run_with_hydra(root: Path, name: str, args: Sequence[str]) -> None:
    import hydra

    load_stage(root, name)  # fail early, before Hydra, with the list of stages
    bconfig.check_renamed_keys((a for a in args if not a.startswith("-")),
                               f"python -m blindspot {name}")
    if not any(a.split("=")[0] in _NO_RUN_FLAGS for a in args):
        missing_inputs(root, name)  # MissingInput naming the files and the stages making them
    os.chdir(root)
    task = _StageTask(str(root), name)
    entry = hydra.main(
        config_path=str(root / bconfig.CONFIG_DIR),
        config_name=bconfig.CONFIG_NAME,
        version_base=None,
    )(task)
    saved = sys.argv
    sys.argv = [f"python -m blindspot {name}", *_hydra_argv(args, name)]
    status = "FAILED"
    try:
        with runs.sigterm_as_exit():
            entry()
        status = "FINISHED"
    except (runs.Terminated, KeyboardInterrupt):
        status = "KILLED"
        raise
    finally:
        sys.argv = saved
        runs.end_open_sweep(status)  # no-op unless a sweep died before on_multirun_end


def _cleanup(root: Path) -> None:
    """What a SIGKILLed stage could not do itself, for when nothing reruns it (DVC restored its
    outputs from the run cache, say): end its MLflow run KILLED and remove its temporaries next
    to every out of dvc.yaml. The next stage run does the same, for its own outs."""
    params = root / bconfig.PARAMS_FILE
    closed = runs.close_stale_runs_of(bconfig.load_params(root) if params.is_file() else None,
                                          root)
    outs = [out for files in read_dvc_stages(root).values() for out in files.outs]
    removed = io.remove_stale_temps(root / out for out in outs)
    print(f"closed {len(closed)} stale run(s) KILLED" + "".join(f"\n  {r}" for r in closed))
    print(f"removed {len(removed)} temporary file(s) of killed writers"
          + "".join(f"\n  {p}" for p in removed))


def stage_summary(repo_root: str | os.PathLike[str], name: str, width: int = 92) -> str:
    """One line about stage ``name``: the first sentence of its module docstring, without the
    leading ``name:``, cut to ``width`` characters. Read with :mod:`ast`, nothing imported."""
    import ast

    path = Path(repo_root) / "stages" / f"{name}.py"
    try:
        doc = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8"))) or ""
    except (OSError, SyntaxError):
        return ""
    text = " ".join(doc.strip().split("\n\n")[0].split())
    if text.startswith(f"{name}:"):
        text = text[len(name) + 1:].strip()
    # the first sentence: ends at '.' before a blank, not after an abbreviation
    m = re.search(r"(?<!\bFig)(?<!\beq)(?<!\bsec)(?<!\bvs)(?<!e\.g)(?<!i\.e)[.](\s|$)", text)
    text = text[: m.start()] if m else text
    return text if len(text) <= width else text[: width - 3].rstrip(" ,;:(") + "..."


def _usage(root: Path | None) -> str:
    cmds = "\n".join(f"  {k:<15} {v}" for k, v in COMMANDS.items())
    if root:
        names = available_stages(root)
        stages = "\n".join(f"  {n:<15} {stage_summary(root, n)}" for n in names)
    else:
        stages = "  (not inside a blindspot repository)"
    return (
        "usage: python -m blindspot <stage> [key=value ...] [-m for a sweep]   (or: blindspot ...)\n"
        "       python -m blindspot <stage> --help      the stage's config groups and keys\n"
        "       python -m blindspot <command> [...]\n"
        f"\nstages (dvc.yaml runs them in order: `make repro`):\n{stages}\n"
        f"\ncommands:\n{cmds}\n"
        "\nA stage's --cfg job prints its composed config, --info Hydra's information.\n"
        "MLflow UI: mlflow ui --backend-store-uri sqlite:///$PWD/mlflow.db"
    )


def _flat_lines(node: object, prefix: str) -> list[str]:
    from omegaconf import DictConfig as _DC

    if isinstance(node, _DC):
        if not node:
            return [f"    {prefix} = {{}}"]
        out = []
        for k in node.keys():
            out.extend(_flat_lines(node.get(k), f"{prefix}.{k}"))
        return out
    if isinstance(node, str):
        text = repr(node)
    elif node is None or isinstance(node, int | float | bool):
        text = str(node)
    else:  # a list
        text = " ".join(OmegaConf.to_yaml(node).split()) if OmegaConf.is_config(node) else str(node)
    return [f"    {prefix} = {text if len(text) <= 70 else text[:67] + '...'}"]


def stage_help(root: Path, name: str) -> str:
    """``python -m blindspot <stage> --help``: what the stage does, the config keys it reads
    (its ``params:`` in dvc.yaml) with their values in params.yaml, the choices of each config
    group under conf/, the outside data it needs and how to override. No Hydra composition."""
    import yaml

    load_stage(root, name)  # UnknownStage with the list of stages
    spec = (yaml.safe_load((root / "dvc.yaml").read_text()) or {}).get("stages", {}).get(name, {})
    keys: list[str] = []
    for item in spec.get("params") or ():
        keys.extend([str(item)] if not isinstance(item, dict)
                    else [str(k) for v in item.values() for k in (v or [])])
    params = OmegaConf.load(root / bconfig.PARAMS_FILE) if (root / bconfig.PARAMS_FILE).is_file() \
        else OmegaConf.create()
    lines = [f"python -m blindspot {name} [key=value ...] [-m for a sweep]",
             "", stage_summary(root, name, width=200), "",
             "config it reads (dvc.yaml params; values as in params.yaml, composed from conf/):"]
    for key in keys or ["(none)"]:
        group = key.split(".")[0]
        options = sorted(p.stem for p in (root / bconfig.CONFIG_DIR / group).glob("*.yaml"))
        head = f"  {key}" + (f"   (group conf/{group}/: {', '.join(options)}; choose with "
                             f"{group}=<name>)" if options and "." not in key else "")
        lines.append(head)
        value = OmegaConf.select(params, key) if keys else None
        if value is not None:
            lines.extend(_flat_lines(value, key)[:40])
    sets = [ds.name for ds in datasets.load_manifest().values() if name in ds.used_by]
    lines += ["", "outside data: " + (", ".join(sets) + " (`python -m blindspot data list`)"
                                      if sets else "none"),
              "", f"override: python -m blindspot {name} <key>=<value> ... | under DVC: "
              f"dvc exp run -S '<key>=<value>'",
              f"also: --cfg job (the composed config), --info (Hydra's information), "
              f"--hydra-help (Hydra's own help)"]
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m blindspot``; returns the process exit status."""
    args = list(sys.argv[1:] if argv is None else argv)
    try:
        root: Path | None = bconfig.find_repo_root()
    except bconfig.ConfigNotFound as exc:
        root = None
        missing_root = exc
    if not args or args[0] in {"-h", "--help", "help"}:
        print(_usage(root))
        return 0 if args else 2
    command, rest = args[0], args[1:]
    if root is None:
        print(f"[blindspot] {missing_root}", file=sys.stderr)
        return 2
    if command == "stages":
        print("\n".join(available_stages(root)))
        return 0
    if command == "data":
        return datasets.main(rest)
    if {"-h", "--help"} & set(rest) and command not in COMMANDS:
        try:
            print(stage_help(root, command))
        except UnknownStage as exc:
            print(f"[blindspot] {exc}", file=sys.stderr)
            return 2
        return 0
    if command in {"params", "check-params", "cleanup"} and rest:
        print(f"[blindspot] `{command}` takes no arguments (got {' '.join(rest)}); "
              "change values in conf/", file=sys.stderr)
        return 2
    if command == "cleanup":
        _cleanup(root)
        return 0
    if command in {"params", "check-params"}:
        from hydra.errors import HydraException

        try:
            if command == "params":
                print(f"wrote {bconfig.write_params(root)}")
            elif os.environ.get("DVC_EXP_NAME"):
                # inside `dvc exp run`, DVC itself composed conf/ + the -S overrides into
                # params.yaml, so it differs from conf/ on purpose (same rule as main_stage)
                print(f"{root / bconfig.PARAMS_FILE}: composed by `dvc exp run` "
                      f"({os.environ['DVC_EXP_NAME']}), not checked against conf/")
            else:
                check_params_stamped(root, stamp=False)  # the pipeline's check: composes
                print(f"{root / bconfig.PARAMS_FILE} is up to date with conf/")
        except bconfig.ParamsOutOfDate as exc:
            print(f"[blindspot] {exc}", file=sys.stderr)
            return 1
        except HydraException as exc:
            print(f"[blindspot] cannot compose {root / bconfig.CONFIG_DIR}: {exc}", file=sys.stderr)
            return 1
        return 0
    try:
        _run_with_hydra(root, command, rest)
    except (UnknownStage, bconfig.RenamedKey) as exc:
        print(f"[blindspot] {exc}", file=sys.stderr)
        return 2
    except MissingInput as exc:
        print(f"[blindspot] {exc}", file=sys.stderr)
        return 1
    return 0
