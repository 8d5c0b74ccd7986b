"""The Doppler half of the moving-object test, tuned on one half of the Monte-Carlo scenes and
reported on the other. Prints figures, asserts nothing.

    BLINDSPOT_SHARED=../shared .venv/bin/python studies/doppler_test.py \
        [--data data] [--predictors constant_velocity,lstm_direct] [--json OUT] \
        [--floors 0,0.1,...] [--spread 0.27,0.79]

The moving test (:func:`blindspot.track.moving.moving_tracks`, settings ``tracker.moving.*``)
has three Doppler settings, chosen on the same simulated set README reports (the "doubtful"
note of docs/studies/safety.md): a point's radial-speed spread ``moving_doppler_std_mps`` (0.3 m/s),
the bound on the summed log-likelihood ratio "moves as tracked" vs "static", ``moving_doppler_log_ratio_min``
(-ln 10), and the ratio's form ``moving_doppler_llr`` (common_variance or marginal,
:func:`blindspot.track.moving.doppler_log_ratio`). Here every candidate is scored the way
clutter scores the evidence grid:

1. the tracker's tracks of the last ``dvc repro`` (DATA/driving/tracks.parquet), classed moving
   by the kinematic test and the configured static-evidence grid only (no Doppler test): a
   superset of the rows any Doppler setting keeps;
2. each predictor's risk rows for that superset, once (:func:`blindspot.safety.predict.risk_table`,
   the calibrated predictor of DATA/calibration/models.json, as the safety stage builds it);
3. per candidate, the rows its moving test keeps; the outcome of every scene behind the configured
   AEB gate and threshold (aeb_gate's machinery), on the tuning half (even replicates,
   :func:`blindspot.safety.evaluation.replicate_half`) and the held-out half (odd).

Per predictor, two picks on the tuning half are reported on the held-out half beside the
configured one and the test switched off: the candidate with the largest avoided minus
false-activation rate (Youden's J), and the one that avoids the most collisions with no false
activation (the issue's <= 1 % goal on 54 scenes; ties broken by J). Candidates:
``moving_doppler_llr`` in {common_variance, marginal} x ``moving_doppler_std_mps`` in
{0.15, 0.3, 0.6} x ``moving_doppler_log_ratio_min`` in {-ln 1000, -ln 100, -ln 10, -ln 3,
-ln 1.5}, each with the configured floor ``moving_doppler_log_ratio_floor`` at the configured
distance below its bound, each without and with the Doppler spread ratio
(``moving_doppler_spread_std_mps``) at the ``--spread`` pair (default 0.27,0.79 m/s: static and
walker, the tuning half's pooled within-object spreads in driving_track.json ``doppler_spread``),
and each with its Doppler judged against the velocity of its frame or the current one
(``moving_doppler_reference``); and the configured test judged frame by frame (the floor acts
on that sum only) with its floor at each ``--floors`` distance below the bound. Time: 4-6 min
on 2 cores.

Conclusion: the Doppler half of the moving test buys 2-3 fewer false activations for 2-4 avoided
collisions (a flat J); it stays for the fewer false activations, not because J asks for it. The
floor ln 0.01 avoids one more collision per half with range_doppler_angle peaks; nearer floors
gain at most one on a tuning half. The micro-Doppler spread (--spread 0.27,0.79) halves false
activations on the simulation but real walkers spread 0.08-0.14 m/s, so it is not used
(conf/warning/default.yaml, docs/studies/safety.md).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads
import numpy as np
import pandas as pd

REPO = Path(__file__).resolve().parents[1]

from aeb_gate import half_counts, half_results, load_inputs, outcome_setup  # noqa: E402
from blindspot.io import write_json  # noqa: E402
from blindspot.safety.predict import risk_table, with_backfill  # noqa: E402
from blindspot.track.moving import moving_test_settings, moving_tracks  # noqa: E402
from blindspot.traj.calibration import from_record  # noqa: E402
from blindspot.track.config import TrackerConfig  # noqa: E402

STDS = (0.15, 0.3, 0.6)
BOUNDS = (-np.log(1000.0), -np.log(100.0), -np.log(10.0), -np.log(3.0), -np.log(1.5))
FORMS = ("common_variance", "marginal")
REFERENCES = ("frame", "current")


def calibrated(cfg, name: str, data: Path):
    """The safety stage's calibrated predictor ``name`` (constant_velocity, kalman or
    lstm_direct), its history backfilled as the stage does."""
    from blindspot.radar.config import RadarConfig
    from blindspot.safety.config import WarningConfig
    from blindspot.traj.baselines import kalman_baseline
    from blindspot.traj.config import EvalConfig
    from blindspot.traj.baselines import ConstantVelocity
    from blindspot.traj.seq2seq import Seq2SeqEnsemble

    ev = EvalConfig.from_cfg(cfg)
    made = {"constant_velocity": lambda: ConstantVelocity(k=ev.cv_fit_points,
                                                          name="constant_velocity"),
            "kalman": lambda: kalman_baseline(EvalConfig.from_cfg(cfg), RadarConfig.from_cfg(cfg).frame_period_s),
            "lstm_direct": lambda: Seq2SeqEnsemble.load(data / "train_direct/model.pt")}
    if name not in made:
        raise SystemExit(f"--predictors: {name!r} is not one of {sorted(made)}")
    point = made[name]()
    record = json.loads((data / "calibration/models.json").read_text())[name]
    return with_backfill(from_record(record, point, name), point,
                         WarningConfig.from_cfg(cfg).lstm_history)


def moving_test_inputs(cfg, data: Path, truth_all: pd.DataFrame):
    """What a moving-test sweep reads besides :func:`aeb_gate.load_inputs`: (the
    Monte-Carlo truth, the driving frame period in s, DATA/driving/tracks.parquet sorted by
    group, track and frame, DATA/driving/points.parquet, the ego's pose per group and frame)."""
    from blindspot.radar.config import RadarConfig
    from blindspot.safety.config import WarningConfig
    from blindspot.traj.baselines import kalman_baseline
    from blindspot.traj.config import EvalConfig

    tracks = pd.read_parquet(data / "driving/tracks.parquet")
    ego = (truth_all.groupby(["scene", "frame"], as_index=False)
           [["ego_x_m", "ego_y_m", "ego_yaw_deg", "ego_speed_mps"]].first()
           .rename(columns={"scene": "group"}))
    return (truth_all[truth_all.set == "monte_carlo"],
            float(RadarConfig.from_cfg(cfg, "driving_radar").frame_period_s),
            tracks.sort_values(["group", "track_id", "frame"]).reset_index(drop=True),
            pd.read_parquet(data / "driving/points.parquet"), ego)


def score_candidates(cfg, w, data: Path, pname: str, sup: pd.DataFrame, ego: pd.DataFrame,
                     dt: float, shape, flags: dict, setup) -> dict:
    """Per candidate moving test (``flags``: name -> (N,) bool over the rows of ``sup``, each a
    subset of ``sup.moving``), predictor ``pname``'s AEB outcome counts on each half
    (:func:`aeb_gate.half_counts` and Youden's J): the risk rows of ``sup``'s moving rows
    are computed once and each candidate keeps those of its own rows."""
    key = ["group", "frame", "track_id"]
    risk = risk_table(sup, ego, {pname: calibrated(cfg, pname, data)},
                      horizon=int(round(w.horizon_s / dt)), dt_s=dt, shape=shape,
                      margin_m=w.pedestrian_radius_m, method=w.probability,
                      max_len=int(round(w.max_history_s / dt)), max_coast_s=w.max_coast_s)
    rows_key = pd.MultiIndex.from_frame(risk[key])
    results = {}
    for name, flag in flags.items():
        kept = pd.MultiIndex.from_frame(sup.loc[flag, key])
        out = results[name] = {}
        for half, res in half_results(risk[rows_key.isin(kept)], setup, w).items():
            o = out[half] = half_counts(res)
            o["j"] = (o["n_avoided"] / max(o["n_intruding"], 1)
                      - o["n_false"] / max(o["n_non_intruding"], 1))
    return results


def main(argv: list[str]) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=REPO / "data")
    ap.add_argument("--predictors", default="constant_velocity,lstm_direct")
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument("--floors", default="0,0.1,0.693,1.099,4.605",
                    help="distances below the configured bound at which the configured test is "
                         "also scored with its floor (comma-separated log ratios)")
    ap.add_argument("--spread", default="0.27,0.79",
                    help="static,walker micro-Doppler spreads (m/s) of the candidates with the "
                         "spread ratio")
    args = ap.parse_args(argv)
    try:
        spread = tuple(float(v) for v in args.spread.split(","))
    except ValueError:
        spread = ()
    if len(spread) != 2 or not 0 < spread[0] < spread[1]:
        ap.error(f"--spread: expected static,walker with 0 < static < walker, found "
                 f"{args.spread!r}")
    from blindspot.radar.config import RadarConfig
    from blindspot.safety.config import WarningConfig
    from blindspot.traj.baselines import kalman_baseline
    from blindspot.traj.config import EvalConfig

    cfg, w, _, bodies, shape, truth_all, meta, _ = load_inputs(args.data, "tracker")
    mv = TrackerConfig.from_cfg(cfg).moving
    truth, dt, tracks, points, ego = moving_test_inputs(cfg, args.data, truth_all)

    # the configured floor's distance below the configured bound (None: no floor)
    configured_below = (None if mv.doppler_log_ratio_floor is None
                        else mv.doppler_log_ratio_min - mv.doppler_log_ratio_floor)

    def moving(form: str | None, std: float | None, bound: float | None,
               below: float | None = None, pair: tuple | None | str = "configured",
               reference: str | None = None) -> np.ndarray:
        """The moving flags of a candidate; its floor ``below`` (default the configured
        distance) under its bound; its spread pair and Doppler reference (default the
        configured ones)."""
        pair = mv.doppler_spread_std_mps if pair == "configured" else pair
        reference = reference or mv.doppler_reference
        below = configured_below if below is None else below
        floor = None if below is None or bound is None else bound - below
        return moving_tracks(tracks, ego=ego[["group", "frame", "ego_x_m", "ego_y_m",
                                              "ego_yaw_deg"]],
                             points=points, **{
                                 **moving_test_settings(mv), "doppler_std_mps": std or 0.3,
                                 "doppler_log_ratio_min": bound,
                                 "doppler_llr": form or "common_variance",
                                 "doppler_log_ratio_floor": floor,
                                 "doppler_spread_std_mps": None if bound is None else pair,
                                 "doppler_reference": reference})

    superset = moving(None, None, None)
    configured = moving(mv.doppler_llr, mv.doppler_std_mps,
                        mv.doppler_log_ratio_min)
    if not np.array_equal(configured, tracks.moving.to_numpy(bool)):
        raise SystemExit(f"{args.data / 'driving/tracks.parquet'}: its moving flag is not the "
                         "configured moving test (params.yaml changed since driving_track ran?)")
    setup = outcome_setup(truth, meta, bodies, shape, w)

    def label(f, s, b, pair, ref):
        return (f"{f} std {s:g} m/s, bound {b:.2f}"
                + ("" if pair is None else f", spread {pair[0]:g}/{pair[1]:g}")
                + ("" if ref == "frame" else f", {ref} velocity"))

    candidates = {"off": (None, None, None),
                  **{label(f, s, b, p, r): (f, s, b, None, p, r)
                     for r in REFERENCES for p in (None, spread) for f in FORMS for s in STDS
                     for b in BOUNDS}}
    name_conf = label(mv.doppler_llr, mv.doppler_std_mps,
                      mv.doppler_log_ratio_min, mv.doppler_spread_std_mps,
                      mv.doppler_reference)
    for d in (float(v) for v in args.floors.split(",") if v):
        # the floor acts on the frame-by-frame sum only
        candidates[f"{name_conf}, frame velocity, floor bound - {d:.2f}"] = (
            mv.doppler_llr, mv.doppler_std_mps, mv.doppler_log_ratio_min, d,
            "configured", "frame")
    flags = {name: moving(*sb) for name, sb in candidates.items()}
    flags[name_conf] = configured
    report: dict = {"input": "tracker", "aeb_threshold": w.aeb_threshold,
                    "configured": name_conf, "predictors": {}}
    sup = tracks.assign(moving=superset)      # histories from every row, as the stage builds them
    for pname in args.predictors.split(","):
        results = score_candidates(cfg, w, args.data, pname, sup, ego, dt, shape, flags, setup)
        best = max((n for n in results if n != "off"), key=lambda n: results[n]["tune"]["j"])
        quiet = [n for n in results if n != "off" and results[n]["tune"]["n_false"] == 0]
        best_quiet = max(quiet, key=lambda n: (results[n]["tune"]["n_avoided"],
                                               results[n]["tune"]["j"])) if quiet else None
        report["predictors"][pname] = {"candidates": results, "chosen_on_tuning_half": best,
                                       "most_avoided_without_false_activation": best_quiet}
        print(f"{pname} (tracker input, AEB at {w.aeb_threshold} behind the gate): tuning half "
              "(even replicates) | held-out half (odd); J = avoided rate - false-activation rate")
        for name, r in results.items():
            mark = ("configured" if name == name_conf else "") + (
                " J-pick" if name == best else "") + (" 0-FA-pick" if name == best_quiet else "")
            print(f"  {name:80s} {mark:28s} " + " | ".join(
                f"avoided {r[h]['n_avoided']}/{r[h]['n_intruding']}, false {r[h]['n_false']}/"
                f"{r[h]['n_non_intruding']}, J {r[h]['j']:+.3f}" for h in ("tune", "held_out")))
    if args.json:
        write_json(args.json, report)


if __name__ == "__main__":
    main(sys.argv[1:])
