"""Where the pipeline test's time goes: the tiny-profile `dvc repro` and `dvc exp run`, per stage.

    .venv/bin/python -m benchmarks.bench_tiny_repro [--rev REV] [--no-exp] [--keep DIR]

(from the repository root: run as a module, it imports the pipeline test's helpers from tests/)

Builds the repository the pipeline test builds (tests/pipeline/test_repro.py: this working tree,
or git revision REV via ``git archive``, on the tiny profile, params.yaml composed, committed),
then runs, as that test does, ``dvc repro`` and its ``dvc exp run`` (``EXP_RUN`` of the test:
``-S train.lr=0.003`` and its target; ``--exp-all`` runs it without the target, every stage a
new model reruns). Every stage
command DVC starts (``python ...``) goes through a shim first on PATH that runs the real
interpreter under ``/usr/bin/time``, so each stage's CPU time (user + sys of the stage process
and its children: other jobs on a shared machine inflate it little) and wall time are recorded.
Prints a table per stage and the totals of each DVC command (CPU of DVC itself included).
Asserts nothing; the pipeline test checks the outputs.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from benchmarks.bench_stage_overhead import timed
from tests.conftest import SHARED
from tests.pipeline.test_repro import EXP_RUN, make_tiny_repo
from tests.pipeline.toy_repo import VENV_BIN, clean_env

REPO = Path(__file__).resolve().parents[1]

SHIM = """#!/bin/sh
exec /usr/bin/time -a -o "$BENCH_TIMES" -f "%U %S %e $DVC_STAGE" "{python}" "$@"
"""


def checkout(dest: Path, rev: str | None) -> Path:
    """The folder whose files the pipeline test copies: this working tree, or a clone at ``rev``
    (``git clone --shared``, so its ``git ls-files`` lists that revision's files)."""
    if rev is None:
        return REPO
    subprocess.run(["git", "clone", "-q", "--shared", "--no-checkout", str(REPO), str(dest)],
                   check=True)
    subprocess.run(["git", "checkout", "-q", rev], cwd=dest, check=True)
    return dest


def stage_times(path: Path) -> list[tuple[str, float, float]]:
    """(stage, CPU s, wall s) per line the shim wrote; python calls outside a stage are '-'."""
    rows = []
    for line in path.read_text().splitlines() if path.exists() else []:
        parts = line.split()
        if len(parts) >= 3 and all(p.replace(".", "", 1).isdigit() for p in parts[:3]):
            name = parts[3] if len(parts) > 3 else "-"
            rows.append((name, float(parts[0]) + float(parts[1]), float(parts[2])))
    return rows


def report(title: str, cpu: float, wall: float, rows: list[tuple[str, float, float]]) -> None:
    print(f"\n{title}: CPU {cpu:.1f} s (all processes), wall {wall:.1f} s")
    stages = [r for r in rows if r[0] != "-"]
    for name, c, w in sorted(stages, key=lambda r: -r[1]):
        print(f"  {name:<28} CPU {c:7.1f}  wall {w:7.1f}")
    print(f"  {len(stages)} stages: CPU {sum(r[1] for r in stages):.1f} s, "
          f"wall {sum(r[2] for r in stages):.1f} s")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rev", default=None, help="git revision to measure (default: worktree)")
    parser.add_argument("--no-exp", action="store_true", help="skip the `dvc exp run`")
    parser.add_argument("--exp-all", action="store_true",
                        help="`dvc exp run -S train.lr=0.003` without the test's target")
    parser.add_argument("--keep", default=None, help="build the repository here and keep it")
    args = parser.parse_args()
    if not (SHARED / "data" / "radar").is_dir():
        raise SystemExit(f"shared recordings not found at {SHARED} (set BLINDSPOT_SHARED)")

    with tempfile.TemporaryDirectory(prefix="blindspot-tiny-repro-") as tmp:
        base = Path(args.keep) if args.keep else Path(tmp)
        src, root = base / "src", base / "repo"
        src = checkout(src, args.rev)
        shim_dir = base / "shim"
        shim_dir.mkdir(parents=True)
        shim = shim_dir / "python"
        shim.write_text(SHIM.format(python=VENV_BIN / "python"))
        shim.chmod(0o755)
        env = clean_env(BLINDSPOT_SHARED=str(SHARED))
        # make_tiny_repo copies REPO_ROOT's files: point it at the checkout.
        import tests.pipeline.test_repro as test_repro

        test_repro.REPO_ROOT = src
        make_tiny_repo(root, env)
        env["PATH"] = f"{shim_dir}{os.pathsep}{env['PATH']}"
        dvc = str(VENV_BIN / "dvc")
        label = args.rev or "working tree"
        print(f"tiny-profile pipeline of {label}; load average before: {os.getloadavg()}")

        env["BENCH_TIMES"] = str(base / "repro.times")
        cpu, wall, _ = timed([dvc, "repro"], root, env)
        report("dvc repro", cpu, wall, stage_times(base / "repro.times"))
        if not args.no_exp:
            for cmd in (["git", "add", "-A"], ["git", "commit", "-qm", "baseline", "--allow-empty"]):
                subprocess.run(cmd, cwd=root, env=env, check=True, capture_output=True)
            env["BENCH_TIMES"] = str(base / "exp.times")
            exp = EXP_RUN[:4] if args.exp_all else EXP_RUN
            cpu, wall, _ = timed([dvc, *exp], root, env)
            report(f"dvc {' '.join(exp)}", cpu, wall, stage_times(base / "exp.times"))
        print(f"\nload average after: {os.getloadavg()}")


if __name__ == "__main__":
    main()
