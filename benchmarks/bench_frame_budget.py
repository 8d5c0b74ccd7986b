"""Tracking + prediction + decision per radar frame on one core, mean and 99th percentile over
the driving scenes' frames (issue 40, part 5: at most 10 ms each). Prints figures, asserts
nothing.

    BLINDSPOT_SHARED=../shared PYTHONPATH=src .venv/bin/python benchmarks/bench_frame_budget.py \
        [--data data] [--scenes N]

The configured tracker (params.yaml ``tracker``, its Doppler-first initiation and moving-object
test included) runs on DATA/driving/points.parquet of N Monte-Carlo scenes spread over the
sorted names (default 24), frame after frame in this process, every thread pool pinned to one
thread, after one warm-up scene (imports, caches); each frame's tracker time is the process time
between the starts of two successive frames (the tracker builds one Stone Soup timestamp per
frame, first in its loop; the last frame to the loop's end), plus the frame's share of the
scene's batched work (input checks, DBSCAN of every frame in one call, the output table, the
moving test). Then, per frame, the decision on
that frame's assessed rows (confirmed, moving, not coasting past warning.max_coast_s): the moving test's evidence for the frame's
rows, the track_state forecast (3 s at 0.1 s) and P(collision) against the ego footprint
(blindspot.safety.risk.collision_risk), timed frame by frame. The moving test runs vectorised
over a scene in the stage; here its cost per frame is the scene's share. Times are CPU time
(time.process_time), so other jobs on a shared machine inflate them little.
"""

from __future__ import annotations

import os
import sys

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_v] = "1"                      # one core, before numpy loads

import argparse  # noqa: E402
import datetime as _dt  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import blindspot  # noqa: E402,F401
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from omegaconf import OmegaConf  # noqa: E402

from blindspot.radar.scenario import load_scenarios  # noqa: E402
from blindspot.track.config import TrackerConfig  # noqa: E402
from blindspot.safety.predict import TrackState, decision_rows, track_state_forecast  # noqa: E402
from blindspot.safety.risk import EgoShape, collision_risk  # noqa: E402
from blindspot.synth.driving_tracks import tracker_input  # noqa: E402
from blindspot.track import tracker as T  # noqa: E402
from blindspot.track.moving import moving_test_settings, moving_tracks  # noqa: E402
from blindspot.traj.baselines import KalmanCV  # noqa: E402

REPO = Path(__file__).resolve().parents[1]


def main(argv: list[str]) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=REPO / "data")
    ap.add_argument("--scenes", type=int, default=24)
    args = ap.parse_args(argv)
    cfg = OmegaConf.load(REPO / "params.yaml")
    tcfg = TrackerConfig.from_cfg(cfg)
    group, _ = load_scenarios(cfg.scenario)
    shape = EgoShape(group.ego.width_m, group.ego.length_m)
    truth = pd.read_parquet(args.data / "driving" / "truth.parquet")
    points = pd.read_parquet(args.data / "driving" / "points.parquet")
    mc = np.sort(truth[truth.set == "monte_carlo"].scene.unique())
    pick = mc[np.linspace(0, len(mc) - 1, min(args.scenes, len(mc))).round().astype(int)]
    stamps: list[float] = []

    class StampedTimedelta:                   # the tracker's clock: one call at each frame's start
        def __getattr__(self, name):
            return getattr(_dt, name)

        @staticmethod
        def timedelta(*a, **kw):
            stamps.append(time.process_time())
            return _dt.timedelta(*a, **kw)
    T.dt = StampedTimedelta()
    step = T._track_group
    ended: list[float] = []

    def timed_group(*a, **kw):               # the frame loop's end
        out = step(*a, **kw)
        ended.append(time.process_time())
        return out
    T._track_group = timed_group
    k = KalmanCV(dt=0.1, process_psd=0.5, meas_std=0.15)

    class Calibrated:                          # the timing does not depend on the scale
        base, scale, options = k, np.ones(30), {}
    pred = TrackState(Calibrated())
    track_ms, decide_ms, rows_per_frame = [], [], []
    first = pick[0]
    T.track_points(*tracker_input(truth[truth.scene == first], points[points.scene == first])[:1],
                   tcfg)                      # warm-up: imports and caches, once per process
    for scene in pick:
        tr_s, pt_s = truth[truth.scene == scene], points[points.scene == scene]
        pts, ego = tracker_input(tr_s, pt_s)
        stamps.clear()
        t0 = time.process_time()
        tracks = T.track_points(pts, tcfg)
        t1 = time.process_time()
        tracks["moving"] = moving_tracks(tracks, ego=ego, **moving_test_settings(tcfg.moving),
                                         points=pt_s[["scene", "frame", "x_m", "y_m",
                                                      "static"]])
        n_frames = max(len(stamps), 1)
        # the scene's batched work (input checks, DBSCAN of every frame in one call, the output
        # table; the moving test over the scene) shared equally by its frames
        shared = ((stamps[0] - t0) + (t1 - ended[-1]) + (time.process_time() - t1)) / n_frames
        steps = np.diff(stamps + [ended[-1]])
        frames = np.sort(pts.frame.unique())[: n_frames]
        track_ms += [(f, scene, ms) for f, ms in zip(frames, 1e3 * (steps + shared))]
        e = tr_s.groupby("frame")[["ego_x_m", "ego_y_m", "ego_yaw_deg", "ego_speed_mps"]].first()
        assessed = decision_rows(tracks, 0.1, cfg.warning.max_coast_s)
        for f, rows in tracks[assessed].groupby("frame"):
            t2 = time.process_time()
            fc = track_state_forecast(pred, rows, 30)
            ee = e.loc[[f] * len(rows)]
            collision_risk(fc, ee[["ego_x_m", "ego_y_m"]].to_numpy(),
                           np.radians(ee.ego_yaw_deg.to_numpy()), ee.ego_speed_mps.to_numpy(),
                           0.1, shape, margin_m=0.3, method="max_step")
            decide_ms.append((f, scene, 1e3 * (time.process_time() - t2)))
            rows_per_frame.append(len(rows))
    tm = pd.DataFrame(track_ms, columns=["frame", "scene", "track"])
    dec = pd.DataFrame(decide_ms, columns=["frame", "scene", "decide"])
    per = tm.merge(dec, on=["frame", "scene"], how="left").fillna({"decide": 0.0})
    per["total"] = per.track + per.decide           # a frame without an assessed row: 0 ms
    print(f"{len(pick)} scenes, {len(per)} frames; assessed rows per deciding frame: mean "
          f"{np.mean(rows_per_frame) if rows_per_frame else 0:.2f}")
    for col, what in (("track", "tracking (+ moving test share)"),
                      ("decide", "prediction + decision"), ("total", "all three")):
        print(f"{what} ms/frame: mean {per[col].mean():.2f}, p99 "
              f"{np.percentile(per[col], 99):.2f}, max {per[col].max():.2f}")
    print("slowest frames (ms):\n" + per.nlargest(5, "total").to_string(index=False,
                                                                       float_format="%.2f"))

if __name__ == "__main__":
    main(sys.argv[1:])
