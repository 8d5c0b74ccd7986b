"""Fixed cost of one pipeline stage process (what every one of the 31 DVC stages pays before and
after its own work): prints figures, asserts nothing.

    .venv/bin/python benchmarks/bench_stage_overhead.py [--stage table2] [--repeat R]
        [--rev REV] [--phases] [--gc]

Copies the repository (the working tree, or git revision REV via ``git archive``, without data/,
reports/ and the MLflow store) to a temporary folder, writes its params.yaml, and runs
``python stages/<stage>.py`` there R + 1 times, the way ``dvc repro`` does (its own ``src/`` on
PYTHONPATH). The first run also creates the SQLite store (MLflow's schema migrations) and is
shown apart. Prints each run's CPU time (user + sys of the child process, so other jobs on a
shared machine inflate it little) and wall time, and their medians. The default stage, table2,
computes almost nothing (one Markdown table), so its time is the fixed cost itself.

``--phases`` also runs the stage once inside a Python process that times each step of
:func:`blindspot.cli.main_stage` (imports, params check, params.yaml read, MLflow import and
store, the run and its logging) as CPU seconds.

``--gc`` also times, in 2 R fresh processes that have imported numpy and pandas (as the stages
have), the import of MLflow's client and SQLAlchemy store with Python's cyclic garbage collector
on and paused (:func:`blindspot.runs.store._gc_paused`, what ``get_client`` does), alternated,
as CPU seconds of the import alone.

Compare two revisions by running it twice, e.g. ``--rev 47eca47`` (before the stamped params
check and the lazy Hydra import) and without ``--rev`` (the working tree).
"""

from __future__ import annotations

import argparse
import io
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SKIP = ("data/", "reports/", "mlflow.db", "mlartifacts/")

PHASES = r'''
import importlib.util, sys, time
T = time.process_time
t = T(); marks = []
def mark(name):
    global t
    now = T(); marks.append((name, now - t)); t = now
import blindspot
from blindspot import cli, config as bconfig
mark("import blindspot, blindspot.cli")
stage = sys.argv[1]
spec = importlib.util.spec_from_file_location("stage", f"stages/{stage}.py")
module = importlib.util.module_from_spec(spec); spec.loader.exec_module(module)
mark(f"import stages/{stage}.py (its libraries)")
root = bconfig.find_repo_root()
bconfig.check_params(root)
mark("params check")
cfg = bconfig.load_params(root)
mark("read params.yaml")
import mlflow
mark("import mlflow")
from blindspot import runs
settings = runs.settings_from_cfg(cfg, root)
runs.get_client(settings); runs.ensure_experiment(settings)
mark("open the SQLite store (store modules, schema check)")
cli.run_stage(module.run, stage, cfg, root, check_outs=True)
mark("run: the stage, its MLflow run and logging")
for name, s in marks:
    print(f"PHASE\t{name}\t{s:.2f}")
'''

GC_IMPORT = r'''
import gc, sys, time
import numpy, pandas  # every stage holds them before MLflow is imported
if sys.argv[1] == "paused":
    gc.disable()
t = time.process_time()
import mlflow.store.tracking.sqlalchemy_store
from mlflow.tracking import MlflowClient
print(time.process_time() - t)
'''


def copy_repo(dest: Path, rev: str | None) -> Path:
    """The tracked (and untracked, not ignored) files of the working tree, or of ``rev``."""
    if rev is not None:
        data = subprocess.run(["git", "archive", "--format=tar", rev], cwd=REPO,
                              capture_output=True, check=True).stdout
        with tarfile.open(fileobj=io.BytesIO(data)) as tar:
            tar.extractall(dest, filter="data")
        return dest
    files = subprocess.run(["git", "ls-files", "-co", "--exclude-standard", "-z"], cwd=REPO,
                           capture_output=True, text=True, check=True).stdout.split("\0")
    for rel in filter(None, files):
        src = REPO / rel
        if src.is_file() and not rel.startswith(SKIP):
            (dest / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dest / rel)
    return dest


def timed(cmd: list[str], cwd: Path, env: dict[str, str]) -> tuple[float, float, str]:
    """(CPU s of ``cmd`` and all its children, wall s, stdout) of one run of ``cmd``; exits
    naming the command and the tails of its output if it fails."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} exited {proc.returncode}:\n{proc.stdout[-3000:]}\n"
                         f"{proc.stderr[-3000:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return cpu, wall, proc.stdout


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--stage", default="table2", help="stage to run (default table2)")
    parser.add_argument("--repeat", type=int, default=3, help="timed runs after the first")
    parser.add_argument("--rev", default=None, help="git revision to measure (default: worktree)")
    parser.add_argument("--phases", action="store_true", help="also time each step in-process")
    parser.add_argument("--gc", action="store_true",
                        help="also time MLflow's import with the garbage collector on / paused")
    args = parser.parse_args()

    with tempfile.TemporaryDirectory(prefix="blindspot-stage-overhead-") as tmp:
        root = copy_repo(Path(tmp) / "repo", args.rev)
        (root / ".dvc").mkdir(exist_ok=True)  # a DVC repository (where the params stamp lives)
        env = {k: v for k, v in os.environ.items()
               if not k.startswith(("MLFLOW_", "DVC_", "BLINDSPOT_MLFLOW"))}
        env["PYTHONPATH"] = str(root / "src")
        py = sys.executable
        subprocess.run([py, "-m", "blindspot", "params"], cwd=root, env=env, check=True,
                       capture_output=True)
        cmd = [py, f"stages/{args.stage}.py"]
        first = timed(cmd, root, env)
        runs = [timed(cmd, root, env) for _ in range(args.repeat)]
        label = args.rev or "working tree"
        print(f"stage {args.stage} ({label}): CPU s per run (user+sys), wall s")
        print(f"  first run (creates the MLflow store): CPU {first[0]:.2f}, wall {first[1]:.2f}")
        for i, (cpu, wall, _) in enumerate(runs, 1):
            print(f"  run {i}: CPU {cpu:.2f}, wall {wall:.2f}")
        print(f"  median of {len(runs)}: CPU {statistics.median(r[0] for r in runs):.2f}, "
              f"wall {statistics.median(r[1] for r in runs):.2f}")
        if args.phases:
            script = Path(tmp) / "phases.py"
            script.write_text(PHASES)
            _, _, out = timed([py, str(script), args.stage], root, env)
            print("  phases (CPU s, one in-process run):")
            for line in out.splitlines():
                if line.startswith("PHASE\t"):
                    _, name, seconds = line.split("\t")
                    print(f"    {name:<55} {float(seconds):6.2f}")
        if args.gc:
            script = Path(tmp) / "gc_import.py"
            script.write_text(GC_IMPORT)
            times: dict[str, list[float]] = {"on": [], "paused": []}
            for _ in range(args.repeat):
                for mode in times:
                    _, _, out = timed([py, str(script), mode], root, env)
                    times[mode].append(float(out.split()[-1]))
            print("  import of MLflow's client and store (CPU s in-process, after numpy, pandas):")
            for mode, values in times.items():
                print(f"    garbage collector {mode:<7} median {statistics.median(values):.2f}  "
                      f"({', '.join(f'{v:.2f}' for v in values)})")


if __name__ == "__main__":
    main()
