"""Speed of the warning step per radar frame: prediction + collision risk of three pedestrian
tracks, each predictor, on one core. Prints figures, asserts nothing.

    BLINDSPOT_SHARED=../shared .venv/bin/python benchmarks/bench_warning.py [--repeat R] [--batch N]

Issue 12's budget: tracking + prediction + risk <= 10 ms per frame with three pedestrians on
one core. Times are CPU time of this process (time.process_time), so other jobs on a shared
machine inflate them little. Tracking: the tracker (conf/tracker/gnn_cv.yaml) over a 50-frame
scene of the three walkers (3 points each), per frame. Kalman: an online system keeps each
track's filtered state, so its row predicts from that state (KalmanCV.forecast_from_state, what
the safety stage does) instead of re-filtering the history. The predictors are the safety
stage's own (calibrated distributions from data/calibration/models.json, data/train/model.pt
and data/train_direct/model.pt, the "none" error model fitted on the validation pairs as the
stage does; run `dvc checkout` or `dvc repro calibration` first); the
tracks are three crossing walkers with 50-frame histories (the longest the stage uses), the ego
at 50 km/h. Tracking itself is the tracker's benchmark.
"""

from __future__ import annotations

import os
import sys

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_v] = "1"                      # one core, before numpy loads

import argparse  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import blindspot  # noqa: E402,F401
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
import torch  # noqa: E402
from omegaconf import OmegaConf  # noqa: E402

from blindspot.safety.config import WarningConfig  # noqa: E402
from blindspot.safety.predict import with_backfill  # noqa: E402
from blindspot.safety.risk import EgoShape, collision_risk  # noqa: E402
from blindspot.track import TrackerConfig, track_points  # noqa: E402
from blindspot.traj.baselines import ConstantVelocity, KalmanCV  # noqa: E402
from blindspot.traj.calibration import calibrate, from_record, path_pairs  # noqa: E402
from blindspot.traj.direct import NAME as DIRECT  # noqa: E402
from blindspot.traj.lstm import LSTMPredictor  # noqa: E402
from blindspot.traj.paths import table_to_arrays  # noqa: E402
from blindspot.traj.seq2seq import Seq2SeqEnsemble  # noqa: E402
from blindspot.traj.stationary import Stationary  # noqa: E402
from blindspot.traj.windows import WindowSet  # noqa: E402

REPO = Path(__file__).resolve().parents[1]


def predictors(params: dict, w: WarningConfig) -> dict:
    lstm = LSTMPredictor.load(REPO / "data/train/model.pt")
    rec = json.loads((REPO / "data/calibration/models.json").read_text())
    ev, cal = params["eval"], params["calibration"]
    base = {"constant_velocity": ConstantVelocity(k=ev["cv_fit_points"], name="constant_velocity"),
            "kalman": KalmanCV(dt=params["radar"]["frame_period_s"], **ev["kalman"]),
            "lstm": lstm}
    if DIRECT in w.predictors:
        base[DIRECT] = Seq2SeqEnsemble.load(REPO / "data/train_direct/model.pt")
    out = {}
    for name in w.predictors:
        if name == "none":
            truth, measured, _ = table_to_arrays(pd.read_parquet(REPO / "data/paths/paths.parquet"))
            val = np.unique(WindowSet.load(REPO / "data/windows/val.parquet").path_id)
            h, f = path_pairs(measured[val], truth[val], params["dataset"]["window"],
                              cal["horizon_frames"], cal["stride"])
            out[name] = calibrate({"none": Stationary()}, h, f, scale_method=cal["scale_method"],
                                  scale_level=cal["scale_level"])["none"]
        else:
            p = from_record(rec[name], base[name], name)
            out[name] = with_backfill(p, base[name], w.lstm_history)
    return out


def main(argv: list[str]) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=50)
    ap.add_argument("--tracks", type=int, default=3)
    ap.add_argument("--batch", type=int, default=3000,
                    help="histories in one batched call (the safety stage's way: every track row "
                         "of every scene in one predict_distribution call); 0 skips it")
    args = ap.parse_args(argv)
    torch.set_num_threads(1)
    params = OmegaConf.to_container(OmegaConf.load(REPO / "params.yaml"))
    w = WarningConfig.from_mapping(params["warning"])
    sc = params["scenario"]["ego"]
    shape = EgoShape(sc["width_m"], sc["length_m"])
    dt = params["driving_radar"]["frame_period_s"]
    horizon = int(round(w.horizon_s / dt))
    preds = predictors(params, w)
    rng = np.random.default_rng(0)
    B, T = args.tracks, int(round(w.max_history_s / dt))
    start = np.c_[rng.uniform(2, 5, B), rng.uniform(-2, 2, B)]
    hist = start[:, None, :] + np.arange(T)[None, :, None] * np.array([-0.139, 0.0]) \
        + rng.normal(0, 0.05, (B, T, 2))
    ego_xy, yaw, speed = np.tile([0.0, -20.0], (B, 1)), np.zeros(B), np.full(B, 13.89)
    total = 0.0
    tcfg = TrackerConfig.from_mapping(params["tracker"])
    pts = pd.DataFrame([(f, f * dt, x + dx, y) for f in range(T) for b in range(B)
                        for x, y in [hist[b, f]] for dx in (-0.15, 0.0, 0.15)],
                       columns=["frame", "time_s", "x_m", "y_m"])
    track_points(pts, tcfg)
    times = []
    for _ in range(max(3, args.repeat // 10)):
        t0 = time.process_time()
        track_points(pts, tcfg)
        times.append((time.process_time() - t0) / T)
    track_ms = 1e3 * float(np.median(times))
    print(f"bench_warning: {B} tracks x {T}-frame histories, horizon {horizon} steps, one core, "
          f"CPU time (process_time), median of {args.repeat}")
    print(f"  tracking (gnn_cv, {B} walkers x 3 points) {track_ms:7.2f} ms per frame")
    kal = preds.get("kalman")
    state = kal.base.filter(hist) if kal is not None else None
    for name, p in preds.items():
        def step():
            if name == "kalman":
                fc = p.base.forecast_from_state(state.means[:, -1], state.covs[:, -1], horizon,
                                                **dict(p.options)).scaled(p.scale[:horizon])
            else:
                fc = p.predict_distribution(hist, horizon)
            return collision_risk(fc, ego_xy, yaw, speed, dt, shape,
                                  margin_m=w.pedestrian_radius_m, method=w.probability)
        step()
        times = []
        for _ in range(args.repeat):
            t0 = time.process_time()
            step()
            times.append(time.process_time() - t0)
        ms = 1e3 * float(np.median(times))
        total += ms
        print(f"  {name:18s} prediction + risk {ms:7.2f} ms per frame; with tracking "
              f"{ms + track_ms:7.2f} ms (budget 10 ms)")
    print(f"  all {len(preds)} predictors     {total:7.2f} ms per frame")
    if args.batch <= 0:
        return
    N = args.batch
    hb = np.concatenate([hist] * (N // B + 1))[:N] + rng.normal(0, 0.05, (N // B + 1) * B)[:N,
                                                                                          None, None]
    eb, yb, sb = np.tile([0.0, -20.0], (N, 1)), np.zeros(N), np.full(N, 13.89)
    print(f"batched: {N} histories in one call per predictor (best of 3), amortised per frame of "
          f"{B} tracks")
    for name, p in preds.items():
        times = []
        for _ in range(3):
            t0 = time.process_time()
            fc = p.predict_distribution(hb, horizon)
            collision_risk(fc, eb, yb, sb, dt, shape, margin_m=w.pedestrian_radius_m,
                           method=w.probability)
            times.append(time.process_time() - t0)
        t = min(times)
        print(f"  {name:18s} {t:7.2f} s per call, {1e3 * t / N * B:7.2f} ms per frame of {B} "
              "tracks")


if __name__ == "__main__":
    main(sys.argv[1:])
