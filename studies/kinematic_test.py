"""The kinematic half of the moving-object test, tuned on one half of the Monte-Carlo scenes and
reported on the other. Prints figures, asserts nothing.

    BLINDSPOT_SHARED=../shared .venv/bin/python studies/kinematic_test.py \
        [--data data] [--predictors constant_velocity,kalman,lstm_direct] \
        [--speeds 0.3,0.5,0.7] [--probabilities 0.8,0.9,0.95,0.99,0.995] [--json OUT]

A confirmed track is a moving object from its first frame whose filtered velocity is faster
than ``tracker.moving.speed_mps`` and non-zero by the chi-square test at
``tracker.moving.probability`` (:func:`blindspot.track.moving.moving_tracks`), with its
Doppler and static-evidence tests on top. Both kinematic settings were chosen on the paper's
CA-CFAR cloud; on a child stepping out the test is what holds the track back
(``moving_diagnosis.py --track``: a 40 km/h child's track at 1.0-1.4 m/s for three frames
with v' P_v^-1 v of 2.4-3.7, below the 0.99 quantile 9.21, while the AEB gate is already open).
Here every pair of ``--speeds`` x ``--probabilities`` is scored the way doppler_test
scores the Doppler settings:

1. the tracker's tracks of the last ``dvc repro`` (DATA/driving/tracks.parquet), classed moving
   by the loosest pair with the configured Doppler test and static-evidence grid: a superset of
   the rows any pair keeps (a looser kinematic test passes more frames, and the latch and the
   grid keep the order);
2. each predictor's risk rows for that superset, once (the calibrated predictor of
   DATA/calibration/models.json, as the safety stage builds it);
3. per pair, the rows its moving test keeps; the outcome of every scene behind the configured
   AEB gate and threshold, on the tuning half (even replicates,
   :func:`blindspot.safety.evaluation.replicate_half`) and the held-out half (odd).

Per predictor the pair with the largest avoided minus false-activation rate (Youden's J) on the
tuning half is marked, and so is the pair with the largest J summed over the predictors (one
setting serves them all); both are reported on the held-out half beside the configured pair.
Time: about 1 min for three predictors.

Conclusion: the speed threshold (0.3 / 0.5 / 0.7 m/s) never decides, the chi-square test binds
first; the probability trades avoided collisions for false activations along a nearly flat J;
the tuning half would pick 0.8 but that raises held-out false activations from 5 / 8 / 7 to 12 /
13 / 13 of 54, so moving_probability 0.99 stays (docs/studies/safety.md, 2026-12-02).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads
import numpy as np
import pandas as pd

REPO = Path(__file__).resolve().parents[1]

from aeb_gate import load_inputs, outcome_setup  # noqa: E402
from doppler_test import moving_test_inputs, score_candidates  # noqa: E402
from blindspot.io import write_json  # noqa: E402
from blindspot.track.moving import moving_test_settings, moving_tracks  # noqa: E402
from blindspot.track.config import TrackerConfig  # noqa: E402


def _floats(text: str, flag: str, lo: float, hi: float) -> list[float]:
    try:
        out = [float(v) for v in text.split(",") if v]
    except ValueError:
        out = []
    if not out or not all(lo < v < hi for v in out):
        raise SystemExit(f"{flag}: expected comma-separated numbers in ({lo:g}, {hi:g}), "
                         f"found {text!r}")
    return out


def main(argv: list[str]) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=REPO / "data")
    ap.add_argument("--predictors", default="constant_velocity,kalman,lstm_direct")
    ap.add_argument("--speeds", default="0.3,0.5,0.7", help="moving_speed_mps candidates, m/s")
    ap.add_argument("--probabilities", default="0.8,0.9,0.95,0.99,0.995",
                    help="moving_probability candidates")
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args(argv)
    speeds = _floats(args.speeds, "--speeds", 0.0, 10.0)
    probabilities = _floats(args.probabilities, "--probabilities", 0.0, 1.0)
    cfg, w, _, bodies, shape, truth_all, meta, _ = load_inputs(args.data, "tracker")
    mv = TrackerConfig.from_cfg(cfg).moving
    speeds = sorted(set(speeds) | {mv.speed_mps})
    probabilities = sorted(set(probabilities) | {mv.probability})
    truth, dt, tracks, points, ego = moving_test_inputs(cfg, args.data, truth_all)

    def moving(speed: float, probability: float) -> np.ndarray:
        return moving_tracks(tracks, ego=ego[["group", "frame", "ego_x_m", "ego_y_m",
                                              "ego_yaw_deg"]],
                             points=points, **{**moving_test_settings(mv), "speed_mps": speed,
                                               "probability": probability})

    flags = {(s, p): moving(s, p) for s in speeds for p in probabilities}
    conf = (mv.speed_mps, mv.probability)
    if not np.array_equal(flags[conf], tracks.moving.to_numpy(bool)):
        raise SystemExit(f"{args.data / 'driving/tracks.parquet'}: its moving flag is not the "
                         "configured moving test (params.yaml changed since driving_track ran?)")
    superset = flags[(speeds[0], probabilities[0])]
    if any((f & ~superset).any() for f in flags.values()):
        raise SystemExit("internal: a candidate keeps a row the loosest pair does not")
    setup = outcome_setup(truth, meta, bodies, shape, w)
    sup = tracks.assign(moving=superset)      # histories from every row, as the stage builds them
    results: dict = {}
    for pname in args.predictors.split(","):
        results[pname] = score_candidates(cfg, w, args.data, pname, sup, ego, dt, shape, flags,
                                          setup)
        print(f"{pname} done", flush=True)
    common = max(flags, key=lambda pr: sum(results[p][pr]["tune"]["j"] for p in results))
    print(f"tracker input, AEB at {w.aeb_threshold} behind the {w.aeb_gate} gate; tuning half "
          "(even replicates) | held-out half (odd); J = avoided rate - false-activation rate; "
          f"configured pair speed {conf[0]:g} m/s, probability {conf[1]:g}")
    for pname, per in results.items():
        best = max(per, key=lambda pr: per[pr]["tune"]["j"])
        print(pname)
        for pair, r in per.items():
            mark = ("configured " if pair == conf else "") + ("J-pick " if pair == best else "") \
                + ("common-pick" if pair == common else "")
            print(f"  speed {pair[0]:4.2f} m/s, probability {pair[1]:5.3f} {mark:32s} " + " | ".join(
                f"avoided {r[h]['n_avoided']}/{r[h]['n_intruding']}, false {r[h]['n_false']}/"
                f"{r[h]['n_non_intruding']}, J {r[h]['j']:+.3f}" for h in ("tune", "held_out")))
    if args.json:
        write_json(args.json, {
            "input": "tracker", "aeb_threshold": w.aeb_threshold,
            "configured": {"speed_mps": conf[0], "probability": conf[1]},
            "common_pick": {"speed_mps": common[0], "probability": common[1]},
            "predictors": {p: [{"speed_mps": pr[0], "probability": pr[1], **r}
                               for pr, r in per.items()] for p, per in results.items()}})


if __name__ == "__main__":
    main(sys.argv[1:])
