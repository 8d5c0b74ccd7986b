"""Speed of the detection chain on one MMWCAS frame, beside the peer chain, in one run.

    python benchmarks/bench_dsp.py [--threads 1] [--batch 64] [--rounds 5]
                                   [--set detect.max_range_m=null]

Runs the peer chain a user would assemble from public libraries (OpenRadar + doa-py,
``../shared/bench/peer_chain.py``, in the venv named by ``PEERBENCH_VENV``; set it up once with
``bash ../shared/bench/setup_peer_venv.sh``) on one frame, dumps that frame, then runs
``python -m blindspot.bench.dsp`` (DESIGN.md's interface) on the same frame with the same thread
pinning, and prints both per-step tables and the ratio of frames/s. The machines are shared, so
only the ratio of two runs made together means something. Without the peer venv it runs ours
alone and says how to get the peer. The peer processes the full 256-bin range: compare with
``--set detect.max_range_m=null`` (the default here) for like with like.

The peer reports wall time only; its CPU time per frame is taken from the process CPU of two of
its runs (13 frames minus 5 frames: start-up, frame synthesis and dump cancel) and printed beside
ours (``time.thread_time``) with the CPU ratio, the steadier figure on a loaded machine.

``--rounds N`` (default 5) repeats the pair N times, peer and ours alternately, and prints each
round's ratio and the median over rounds. On the shared 2-core VM both chains' times swing by
20-45 % over minutes (every step of a chain slower together, then not), so one pair measured a
minute apart can land on opposite sides of a swing; alternating in rounds exposes both to the
same stretches, and the median over rounds is the figure to quote.

``--baseline REV`` instead compares two versions of our own chain in one process, on the same
frame: the package as committed at git revision REV (exported with ``git archive`` into a
temporary directory and imported under another name) and the working tree's, run alternately
``--repeats`` times on one thread, with every step timed in CPU time (``time.process_time``, so
other load on the machine changes the figures less than it changes wall time). It prints the
median per step and in total for both, their ratio, and whether the two give the same detection
cells and angles (largest angle difference).

Measured 2026-11-30 with ``--threads 1`` (three runs, 2-core AMD EPYC shared with other jobs, load
7.5-8.2): ours 96-115 ms wall, 38.6-46.7 ms CPU per frame; the peer 958-1181 ms wall, 347-423 ms
CPU; ratio 10.0x / 10.0x / 10.3x (wall), 10.0x / 8.3x / 9.0x (CPU); batches of 64 frames 5.5-9.3
frames/s (README, "Tests and benchmarks").
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]


def _shared() -> Path:
    return Path(os.environ.get("BLINDSPOT_SHARED", REPO.parent / "shared")).resolve()


def _children_cpu_s() -> float:
    """User + system CPU seconds of all finished child processes so far."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def _run(cmd: list[str], threads: int, quiet: bool = False) -> tuple[dict, float]:
    """(the JSON summary on the last stdout line, the child's CPU seconds)."""
    env = {**os.environ, "OMP_NUM_THREADS": str(threads), "OPENBLAS_NUM_THREADS": str(threads),
           "MKL_NUM_THREADS": str(threads)}
    cpu0 = _children_cpu_s()
    out = subprocess.run(cmd, env=env, capture_output=True, text=True, check=False)
    cpu = _children_cpu_s() - cpu0
    if out.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed ({out.returncode}):\n{out.stderr[-2000:]}")
    if not quiet:
        print(out.stdout.rstrip())
    return json.loads(out.stdout.strip().splitlines()[-1]), cpu


_BASELINE_RUN = r"""
import os, sys, time
import numpy as np
from threadpoolctl import threadpool_limits
threadpool_limits(1)
import torch
torch.set_num_threads(1)
from blindspot.dsp.config import CfarConfig, DetectConfig, DoaConfig
from blindspot.radar.array import array_for
from blindspot.radar.config import RadarConfig
from blindspot.config import compose
import blindspot.dsp.chain as new_chain
import blindspot_baseline.dsp.chain as old_chain
from blindspot.bench.dsp import simulated_frame
repeats, overrides = int(sys.argv[2]), sys.argv[3:]
cfg = compose(["radar.adc_bits=16", "detect.workers=1"] + overrides)
radar, array = RadarConfig.from_cfg(cfg), array_for(RadarConfig.from_cfg(cfg))
cube, label = simulated_frame(cfg, radar)
groups = (radar, array, CfarConfig.from_cfg(cfg), DoaConfig.from_cfg(cfg), DetectConfig.from_cfg(cfg))
chains = {"baseline": old_chain.DetectionChain(*groups), "ours": new_chain.DetectionChain(*groups)}
# each chain times its steps with its module's time.perf_counter: CPU time instead
cpu_clock = type(sys)("cpu_clock")
cpu_clock.perf_counter = time.process_time
old_chain.time = new_chain.time = cpu_clock
steps = {k: [] for k in chains}
total = {k: [] for k in chains}
for c in chains.values():
    for _ in range(3):
        c.process(cube)
for _ in range(repeats):  # alternately, so both see the same load
    for k, c in chains.items():
        t0 = time.process_time()
        res = c.process(cube)
        total[k].append((time.process_time() - t0) * 1e3)
        steps[k].append(res.timings_ms)
print(f"frame: {label}; {repeats} alternate runs each, one thread, CPU time (process_time), "
      f"load average {os.getloadavg()[0]:.1f}")
names = list(dict.fromkeys(n for k in chains for n in steps[k][0]))
print(f"  {'step':<14s} {'baseline':>9s} {'ours':>9s}  ms CPU (median)")
for n in names:
    b, o = (float(np.median([s.get(n, 0.0) for s in steps[k]])) for k in chains)
    print(f"  {n:<14s} {b:9.2f} {o:9.2f}")
b, o = (float(np.median(total[k])) for k in chains)
print(f"  {'total':<14s} {b:9.2f} {o:9.2f}  (ours / baseline {o / b:.3f})")
rb, ro = (c.process(cube).detections for c in chains.values())
cells = ["frame", "range_bin", "doppler_bin", "moving"]
same = rb[cells].equals(ro[cells])
diff = np.abs(rb["angle_deg"].to_numpy() - ro["angle_deg"].to_numpy())
print(f"same detection cells: {same}; largest angle difference "
      f"{np.nanmax(diff, initial=0.0):.2e} deg over {len(ro)} detections")
"""


def _baseline(rev: str, repeats: int, overrides: list[str]) -> int:
    """Per-step CPU time of the chain at git revision ``rev`` and of the working tree's, in one
    process (module docstring)."""
    import re
    import tarfile

    with tempfile.TemporaryDirectory() as tmp:
        archive = Path(tmp) / "src.tar"
        with archive.open("wb") as fh:
            done = subprocess.run(["git", "-C", str(REPO), "archive", rev, "src/blindspot"],
                                  stdout=fh, stderr=subprocess.PIPE, check=False)
        if done.returncode != 0:
            raise SystemExit(f"--baseline {rev}: git archive failed: {done.stderr.decode()}")
        with tarfile.open(archive) as tar:
            tar.extractall(tmp, filter="data")
        pkg = Path(tmp) / "blindspot_baseline"
        (Path(tmp) / "src" / "blindspot").rename(pkg)
        # the revision's own modules import each other as blindspot.*: point them at the copy
        pattern = re.compile(r"\bblindspot(?=[.\s])")
        for f in pkg.rglob("*.py"):
            f.write_text(pattern.sub("blindspot_baseline", f.read_text()))
        env = {**os.environ, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1",
               "MKL_NUM_THREADS": "1",   # the copy importable as blindspot_baseline
               "PYTHONPATH": os.pathsep.join(filter(None, [tmp, os.environ.get("PYTHONPATH")]))}
        return subprocess.run([sys.executable, "-c", _BASELINE_RUN, tmp, str(repeats),
                               *overrides], env=env, check=False).returncode


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--batch", type=int, default=64, help="frames/s of a batch of N (0: skip)")
    ap.add_argument("--repeats", type=int, default=30)
    ap.add_argument("--rounds", type=int, default=5,
                    help="peer and ours measured alternately this many times (median ratio)")
    ap.add_argument("--set", dest="overrides", action="append", default=None,
                    metavar="KEY=VALUE", help="Hydra overrides for our chain "
                    "(default: detect.max_range_m=null, the peer's full range)")
    ap.add_argument("--baseline", metavar="REV", help="instead: our chain at git revision REV "
                    "beside the working tree's, per-step CPU time in one process")
    args = ap.parse_args()
    overrides = args.overrides if args.overrides is not None else ["detect.max_range_m=null"]
    if args.baseline:
        return _baseline(args.baseline, args.repeats, overrides)
    ours = [sys.executable, "-m", "blindspot.bench.dsp", "--threads", str(args.threads),
            "--json", "--repeats", str(args.repeats), "--batch", str(args.batch)]
    for o in overrides:
        ours += ["--set", o]
    venv = os.environ.get("PEERBENCH_VENV")
    peer_python = Path(venv, "bin", "python") if venv else None
    if peer_python is None or not peer_python.is_file():
        print(f"peer chain: not run (PEERBENCH_VENV={venv!r} has no bin/python; set it up with "
              f"`PEERBENCH_VENV=... bash {_shared() / 'bench' / 'setup_peer_venv.sh'}`)")
        _run(ours, args.threads)
        return 0
    peer_cmd = [str(peer_python), str(_shared() / "bench" / "peer_chain.py"), "--threads",
                str(args.threads), "--json"]
    if args.rounds < 1:
        ap.error("--rounds must be >= 1")
    rounds = []
    with tempfile.TemporaryDirectory() as tmp:
        frame = Path(tmp) / "frame.npz"
        for k in range(args.rounds):
            last = k == args.rounds - 1   # the tables of the last round are printed
            print(f"== round {k + 1} of {args.rounds}: peer chain (OpenRadar + doa-py)")
            peer, cpu_long = _run(peer_cmd + ["--reps", "12", "--warmup", "1", "--dump-frame",
                                              str(frame)], args.threads, quiet=not last)
            # the peer reports wall time only: its CPU time per frame is the difference of the
            # process CPU of this run (13 frames) and of a run of 5 frames (start-up, the
            # frame's synthesis and its dump cancel)
            _, cpu_short = _run(peer_cmd + ["--reps", "5", "--warmup", "0", "--dump-frame",
                                            str(Path(tmp) / "again.npz")], args.threads,
                                quiet=True)
            peer_cpu_ms = (cpu_long - cpu_short) / (13 - 5) * 1e3
            print(f"== round {k + 1}: blindspot chain, same frame")
            mine, _ = _run(ours + ["--frame", str(frame)] + ([] if last else ["--batch", "0"]),
                           args.threads, quiet=not last)
            rounds.append((peer["ms_per_frame"], mine["ms_per_frame"], peer_cpu_ms,
                           mine["cpu_ms_per_frame"]))
            print(f"   peer {peer['ms_per_frame']:.1f} ms ({peer_cpu_ms:.1f} CPU), ours "
                  f"{mine['ms_per_frame']:.1f} ms ({mine['cpu_ms_per_frame']:.1f} CPU): "
                  f"{peer['ms_per_frame'] / mine['ms_per_frame']:.1f}x wall, "
                  f"{peer_cpu_ms / mine['cpu_ms_per_frame']:.1f}x CPU")
    r = np.array(rounds)                                   # (rounds, 4)
    wall, cpu = r[:, 0] / r[:, 1], r[:, 2] / r[:, 3]
    print(f"\nratio (ours / peer), one frame, {args.threads} thread(s), {args.rounds} "
          f"alternating rounds: median {np.median(wall):.1f}x (rounds "
          f"{', '.join(f'{x:.1f}' for x in wall)}); median frame times ours "
          f"{np.median(r[:, 1]):.1f} ms, peer {np.median(r[:, 0]):.1f} ms")
    print(f"ratio of CPU time per frame: median {np.median(cpu):.1f}x (rounds "
          f"{', '.join(f'{x:.1f}' for x in cpu)}); load average {os.getloadavg()[0]:.1f}")
    if mine.get("batch_fps"):
        print(f"ratio, ours in batches of {args.batch} (last round): "
              f"{mine['batch_fps'] * r[-1, 0] / 1e3:.1f}x ({mine['batch_fps']:.1f} frames/s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
