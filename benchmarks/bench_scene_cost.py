"""CPU time per Monte-Carlo driving scene of the stages that grow with the scene count
(driving_measure, driving_track, safety), one core: prints figures, asserts nothing.

    BLINDSPOT_SHARED=../shared PYTHONPATH=src .venv/bin/python benchmarks/bench_scene_cost.py \
        [--data DATA] [--scenes N] [--parts measure track safety] [--save DIR] [--compare DIR]

N Monte-Carlo scenes (default 24) spread over the sorted names of the stage's own scene list
(stages/driving_measure.py: named, nominal and drawn scenes), each part in this process with
every thread pool pinned to one thread, after a one-scene warm-up (imports, the CFAR's factor
table, Stone Soup's models: costs a stage pays once, not per scene):

* ``measure``: :func:`blindspot.synth.driving_measurement.measure_driving` of the N scenes (one
  call, the stage's batching of 48 frames; the batches' noise depends on their position in the
  call, so compare runs of the same N only);
* ``track``: :func:`blindspot.synth.driving_tracks.driving_tracks` (the tracker, the moving test,
  the oracle and visible-truth references, the scoring) on DATA/driving/{truth,points}.parquet of
  those scenes (the stage's inputs, so the same points before and after a change);
* ``safety``: stages/safety.py's ``run`` on DATA's inputs cut to the named scenes plus N
  (twice: the first run warms up) and then 2N Monte-Carlo scenes (outputs to a temporary
  directory); the difference of the last two, per added scene, is the cost per Monte-Carlo
  scene (the fixed costs cancel: calibration, the named scenes).

Times are CPU seconds (``time.process_time``), so other jobs on a shared machine inflate them
little. ``--save DIR`` writes the measured points, the pedestrians' points and the three track
tables; ``--compare DIR`` prints, per table and column, whether this run's equals DIR's and the
largest absolute difference: run ``--save`` with the old code on PYTHONPATH, then ``--compare``
with the new.
"""

from __future__ import annotations

import os
import sys

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_v] = "1"                      # one core, before numpy loads

import argparse  # noqa: E402
import importlib.util  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import blindspot  # noqa: E402,F401
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from omegaconf import OmegaConf  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
TRACK_TABLES = ("tracks", "tracks_oracle", "tracks_noisy_position")


def _measure(cfg, names: list[str]) -> tuple[float, dict[str, pd.DataFrame]]:
    from blindspot.dsp.config import CfarConfig, DetectConfig, DoaConfig, EgoMotionConfig
    from blindspot.radar.config import RadarConfig, SimConfig
    from blindspot.radar.driving import draw_scenarios
    from blindspot.radar.scenario import load_scenarios
    from blindspot.safety.ncap import nominal_scenes
    from blindspot.synth.driving_measurement import measure_driving

    group, named = load_scenarios(cfg.scenario)
    scenes = (list(named.values()) + nominal_scenes(named, group.monte_carlo.speeds_kmh)
              + draw_scenarios(group, named[group.figure_scene]))
    by_name = {s.name: s for s in scenes}
    args = (group, RadarConfig.from_cfg(cfg, "driving_radar"),
            CfarConfig.from_cfg(cfg, "driving_cfar"), DoaConfig.from_cfg(cfg),
            DetectConfig.from_cfg(cfg), EgoMotionConfig.from_cfg(cfg))
    kw = dict(adc_headroom_db=SimConfig.from_cfg(cfg).adc_headroom_db, jobs=1)
    measure_driving([by_name[names[0]]], *args, **kw)                       # warm-up
    t0 = time.process_time()
    res = measure_driving([by_name[n] for n in names], *args, **kw)
    return time.process_time() - t0, {"points": res.points, "measured": res.measured}


def _track(cfg, truth, points) -> tuple[float, dict[str, pd.DataFrame]]:
    from blindspot.radar.config import RadarConfig
    from blindspot.safety.config import WarningConfig
    from blindspot.synth.driving_tracks import driving_tracks
    from blindspot.track.config import TrackerConfig

    w = WarningConfig.from_cfg(cfg)

    def run(tr, pt):
        return driving_tracks(tr, pt, TrackerConfig.from_cfg(cfg), w.oracle, seed=w.seed,
                              frame_period_s=float(RadarConfig.from_cfg(
                                  cfg, "driving_radar").frame_period_s), jobs=1)[0]
    first = truth.scene.iloc[0]
    run(truth[truth.scene == first], points[points.scene == first])          # warm-up
    t0 = time.process_time()
    tables = run(truth, points)
    return time.process_time() - t0, tables


def _safety(cfg, data: Path, truth_all, mc: list[str], n: int) -> float:
    """CPU per Monte-Carlo scene of the safety stage: (t(named + 2n) - t(named + n)) / n."""
    spec = importlib.util.spec_from_file_location("safety_stage", REPO / "stages" / "safety.py")
    stage = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(stage)
    named = set(truth_all.scene[truth_all.set != "monte_carlo"])
    pick = np.linspace(0, len(mc) - 1, min(2 * n, len(mc))).round().astype(int)
    times = []
    with tempfile.TemporaryDirectory() as tmp:
        # the first run (the smaller set) only warms up: torch's and the predictors' imports
        for run, chosen in enumerate((pick[::2], pick[::2], pick)):
            keep = named | {mc[i] for i in chosen}
            cut = Path(tmp) / f"in{run}"
            cut.mkdir()
            for f in ("truth", "points") + TRACK_TABLES:
                d = pd.read_parquet(data / "driving" / f"{f}.parquet")
                d[d["scene" if "scene" in d else "group"].isin(keep)].to_parquet(
                    cut / f"{f}.parquet")
            deps = {"scenes.json": "driving/scenes.json", "models.json": "calibration/models.json",
                    "train/model.pt": "train/model.pt", "val.parquet": "windows/val.parquet",
                    "train_direct/model.pt": "train_direct/model.pt",
                    "paths.parquet": "paths/paths.parquet",
                    "safety_tuning.json": "../reports/metrics/safety_tuning.json",
                    "safety_held_out.json": "../reports/metrics/safety_held_out.json"}

            class Ctx:
                def dep(self, key, cut=cut):
                    return cut / key if (cut / key).exists() else data / deps[key]

                def out(self, key, tmp=tmp):
                    return Path(tmp) / key
            t0 = time.process_time()
            stage.run(cfg, Ctx())
            times.append((len(chosen), time.process_time() - t0))
    (k1, t1), (k2, t2) = times[1:]
    return (t2 - t1) / (k2 - k1)


def _compare(tables: dict[str, pd.DataFrame], ref_dir: Path) -> None:
    for name, now in tables.items():
        ref = pd.read_parquet(ref_dir / f"{name}.parquet")
        now = now.reset_index(drop=True)
        if ref.shape != now.shape or list(ref.columns) != list(now.columns):
            print(f"  {name}: shape {now.shape} against {ref.shape}: DIFFERENT")
            continue
        worst = {}
        for c in ref.columns:
            a, b = ref[c].to_numpy(), now[c].to_numpy()
            if a.dtype.kind in "fc":
                same_nan = np.array_equal(np.isnan(a), np.isnan(b))
                d = float(np.nanmax(np.abs(a - b))) if np.isfinite(a).any() else 0.0
                if d or not same_nan:
                    worst[c] = d if same_nan else "NaN pattern differs"
            elif not np.array_equal(a, b):
                worst[c] = f"{int((a != b).sum())} values differ"
        print(f"  {name} ({len(now)} rows): "
              + ("equal, same bytes" if ref.equals(now) and not worst else f"differs: {worst}"))


def main(argv: list[str]) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=REPO / "data")
    ap.add_argument("--scenes", type=int, default=24)
    ap.add_argument("--parts", nargs="+", default=["measure", "track", "safety"],
                    choices=["measure", "track", "safety"])
    ap.add_argument("--save", type=Path)
    ap.add_argument("--compare", type=Path)
    args = ap.parse_args(argv)
    cfg = OmegaConf.load(REPO / "params.yaml")
    cfg.jobs = 1
    truth = pd.read_parquet(args.data / "driving" / "truth.parquet")
    mc = sorted(truth[truth.set == "monte_carlo"].scene.unique())
    names = [mc[i] for i in np.linspace(0, len(mc) - 1, min(args.scenes, len(mc)))
             .round().astype(int)]
    n = len(names)
    tables: dict[str, pd.DataFrame] = {}
    print(f"{n} Monte-Carlo scenes, one core, CPU seconds per scene:")
    if "measure" in args.parts:
        t, out = _measure(cfg, names)
        tables.update(out)
        print(f"  driving_measure: {t / n:.3f} s ({len(out['points'])} points)")
    if "track" in args.parts:
        points = pd.read_parquet(args.data / "driving" / "points.parquet")
        t, out = _track(cfg, truth[truth.scene.isin(names)], points[points.scene.isin(names)])
        tables.update(out)
        print(f"  driving_track: {t / n:.3f} s ({len(out['tracks'])} tracker rows)")
    if "safety" in args.parts:
        print(f"  safety: {_safety(cfg, args.data, truth, mc, n):.3f} s (difference of "
              f"{n} and {2 * n} Monte-Carlo scenes)")
    if args.save:
        args.save.mkdir(parents=True, exist_ok=True)
        for name, table in tables.items():
            table.to_parquet(args.save / f"{name}.parquet")
    if args.compare:
        print(f"against {args.compare}:")
        _compare(tables, args.compare)


if __name__ == "__main__":
    main(sys.argv[1:])
