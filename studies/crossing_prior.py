"""The tracker with settings given as overrides on one half of the Monte-Carlo draw, then the
safety stage's assessment of chosen predictors on its tracks (issue 40): avoided after visible,
false activations, first point -> moving and -> AEB request (medians), and per speed the avoided
rate and the median TTC at the AEB request. Prints figures, asserts nothing.

    BLINDSPOT_SHARED=../shared PYTHONPATH=src .venv/bin/python studies/crossing_prior.py \
        [--data data] [--half tuning|held_out|all] [--predictors track_state,constant_velocity] \
        [--swap-velocity LLR] [--true-state [--velocity-lag K]] [--warning key=value ...] \
        [tracker overrides key=value ...]

Overrides as studies/first_point.py (e.g. doppler_update_std_mps=1.0
moving.crossing_log_ratio=1.0, null for off). ``--swap-velocity LLR``: the rows of young tracks
(within ``moving.crossing_window`` measured rows) whose crossing evidence reaches LLR carry the
velocity under the crossing prior (:func:`blindspot.track.crossing.crossing_state`) instead of
the tracker's. ``--true-state``: the true state of every pedestrian at every frame in line of
sight instead of the tracker (the decision rule's bound on the same half); with ``--velocity-lag K`` each true-state row carries
the true velocity its pedestrian had K frames earlier (in sight or not): the decision on exact
positions with a velocity K frames late. ``--half all``: the whole main draw (both halves; the independent tuning and held-out
draws of the safety_tuning / safety_held_out stages are not read here).
``--warning key=value``: a ``warning`` setting for
the decision (e.g. max_coast_s=null, aeb_gate_margin_s=0.1). Reads data/driving (truth, points, scenes.json) and the
predictors' models (data/calibration/models.json, data/train*/model.pt, data/paths,
data/windows/val.parquet). Time: about a minute of CPU per run (the tracker on 108 scenes).

Conclusion (2026-12-05, tuning half, docs/studies/first-point-to-brake.md): the per-hit Doppler
update at 1.0 m/s and the crossing test at ln ratio 1.0 take the median first point -> moving
from 0.60 to 0.30 s and track_state's avoided-after-visible from 0.37 to 0.50 at 7.4 % false
activations (5.6 % before); swapping in the crossing prior's velocity adds false activations
(22 %) and avoids no more (0.48): not adopted. Third pass (same half): the approach test at
0.9 and no decision on tracks coasting over 0.1 s take it to 0.593 at 5.6 % false activations.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads
import numpy as np
import pandas as pd
import yaml
from omegaconf import OmegaConf
from scipy.stats import chi2, norm

from blindspot.radar.scenario import load_scenarios
from blindspot.safety.assess import assess
from blindspot.safety.config import WarningConfig
from blindspot.safety.evaluation import replicate_half
from blindspot.safety.oracle import true_state_tracks
from blindspot.safety.outcome import body_boxes
from blindspot.safety.predict import calibrated_predictors
from blindspot.safety.risk import EgoShape
from blindspot.track.crossing import approach_z, crossing_evidence, crossing_state
from blindspot.track.moving import (coast_frames, doppler_evidence, moving_test_settings,
                                     track_static_evidence, velocity_chi2)
from blindspot.traj.baselines import prediction_methods
from blindspot.traj.config import CalibrationConfig, DatasetConfig, EvalConfig
from blindspot.traj.lstm import LSTMPredictor
from first_point import tracked, tracker_config  # studies/ is on a script's path

REPO = Path(__file__).resolve().parents[1]


def _young(tracks: pd.DataFrame, window: int) -> np.ndarray:
    """(N,) bool: the row is within its track's first ``window`` measured rows."""
    t = tracks.reset_index(drop=True)
    order = np.lexsort((t.frame.to_numpy(), t.track_id.to_numpy(), t.group.to_numpy()))
    key = (t.group.astype(str) + "#" + t.track_id.astype(str)).to_numpy()[order]
    rank = pd.Series((t.n_points.to_numpy()[order] > 0).astype(int)).groupby(key).cumsum()
    out = np.empty(len(t), bool)
    out[order] = rank.to_numpy() <= window
    return out


def _late_velocity(ts: pd.DataFrame, truth: pd.DataFrame, lag: int) -> pd.DataFrame:
    """``ts`` (true-state tracks) with each row's velocity replaced by its pedestrian's true
    velocity ``lag`` frames earlier (from the whole truth, in sight or not; a row within the
    scene's first ``lag`` frames keeps its own)."""
    late = truth[["scene", "pedestrian", "frame", "vx_mps", "vy_mps"]].rename(
        columns={"scene": "group", "vx_mps": "vx_late", "vy_mps": "vy_late"})
    late = late.assign(frame=late.frame + lag)
    out = ts.merge(late, on=["group", "pedestrian", "frame"], how="left", validate="1:1")
    out["vx_mps"] = out.vx_late.fillna(out.vx_mps)
    out["vy_mps"] = out.vy_late.fillna(out.vy_mps)
    return out.drop(columns=["vx_late", "vy_late"])


def _frames_since_turn(truth: pd.DataFrame, scene: str, pedestrian: str, frame: int,
                       change_mps: float = 0.3) -> int | None:
    """Frames from the last frame at or before ``frame`` at which ``pedestrian``'s true
    velocity changed by more than ``change_mps`` over one frame (a turn, a start or a stop) to
    ``frame``; None when it never changed."""
    p = truth[(truth.scene == scene) & (truth.pedestrian == pedestrian)
              & (truth.frame <= frame)].sort_values("frame")
    dv = np.hypot(p.vx_mps.diff(), p.vy_mps.diff()).to_numpy()
    changed = p.frame.to_numpy()[np.nan_to_num(dv) > change_mps]
    return int(frame - changed.max()) if changed.size else None


def dissect(res, tracks: pd.DataFrame, truth: pd.DataFrame, points: pd.DataFrame,
            ego: pd.DataFrame, tcfg, predictor: str) -> None:
    """Print what held the decision back (``--dissect``): per false activation the track row
    that requested it (its frames since the last radar point, the nearest true pedestrian's
    distance and behaviour, and how many frames before the request that pedestrian's velocity
    last changed by more than 0.3 m/s); and of the lead pedestrian's confirmed rows before its
    track was first classed moving (before the collision), the share failing each of the
    moving test's parts. The lead's track: the one with most rows within 0.7 m of p0's true
    position."""
    m = tcfg.moving
    sc = res.scenes[(res.scenes.predictor == predictor) & (res.scenes.input == "tracker")]
    fa = sc[~sc.intruding & (sc.aeb_frame >= 0)]
    risk = res.risk[(res.risk.predictor == predictor) & (res.risk.input == "tracker")]
    tr = tracks.assign(coast=coast_frames(tracks))
    print(f"false activations: {len(fa)} of {int((~sc.intruding).sum())} non-intruding scenes")
    for s in fa.itertuples():
        r = risk[(risk.group == s.scene) & (risk.frame == s.aeb_frame)]
        r = r.sort_values("p_collision").iloc[-1]
        row = tr[(tr.group == s.scene) & (tr.track_id == r.track_id)
                 & (tr.frame == s.aeb_frame)].iloc[0]
        t = truth[(truth.scene == s.scene) & (truth.frame == s.aeb_frame)]
        d = np.hypot(t.x_m - row.x_m, t.y_m - row.y_m)
        near = t.iloc[int(np.argmin(d.to_numpy()))]
        turn = _frames_since_turn(truth, s.scene, near.pedestrian, int(s.aeb_frame))
        print(f"  {s.scene}: track {r.track_id}, {row.coast} frames since its last point, "
              f"nearest pedestrian {d.min():.2f} m ({near.behaviour}; its velocity last "
              f"changed by > 0.3 m/s "
              + ("never" if turn is None else f"{turn} frames before the request") + ")")
    p0 = truth[truth.pedestrian == "p0"][["scene", "frame", "x_m", "y_m", "collision_time_s",
                                          "time_s"]].rename(columns={"scene": "group"})
    on = tracks.merge(p0, on=["group", "frame"], suffixes=("", "_p0"))
    on = on[np.hypot(on.x_m - on.x_m_p0, on.y_m - on.y_m_p0) < 0.7]
    lead = on.groupby(["group", "track_id"]).size().reset_index().sort_values(0)
    lead = lead.groupby("group").tail(1)[["group", "track_id"]]
    parts = {"speed": np.hypot(tracks.vx_mps, tracks.vy_mps).to_numpy() > m.speed_mps,
             "chi-square": velocity_chi2(tracks) > chi2.ppf(m.probability, 2),
             "Doppler refutation": doppler_evidence(
                 tracks, ego, m.doppler_std_mps, m.doppler_llr, m.doppler_log_ratio_floor,
                 spread_std_mps=m.doppler_spread_std_mps, reference=m.doppler_reference)
             > m.doppler_log_ratio_min,
             "static grid": track_static_evidence(
                 tracks, points[["scene", "frame", "x_m", "y_m", "static"]],
                 cell_m=m.static_cell_m, lag_frames=m.static_lag_frames)
             < m.static_evidence_min}
    if m.approach_probability is not None:
        parts["approach"] = (approach_z(tracks, ego, m.crossing_corridor_m)
                             > norm.ppf(m.approach_probability))
    t = tracks.assign(**{k: v for k, v in parts.items()}).merge(lead, on=["group", "track_id"])
    t = t.merge(p0[["group", "frame", "collision_time_s"]], on=["group", "frame"])
    first = t[t.moving].groupby("group").frame.min()
    pre = t[t.confirmed & (t.frame < t.group.map(first).fillna(np.inf))
            & (t.time_s <= t.collision_time_s) & t.group.isin(sc[sc.intruding].scene)]
    print(f"lead's confirmed rows before it was classed moving: {len(pre)} in "
          f"{pre.group.nunique()} scenes; failing " + ", ".join(
              f"{k} {1 - pre[k].mean():.0%}" for k in parts))


def study_predictors(cfg, w: WarningConfig, d: Path, wanted: list[str]) -> dict:
    """The safety stage's calibrated predictors named in ``wanted``, from a finished run's
    models under ``d`` (data/: train, train_direct, calibration, paths, windows)."""
    ev, dt = EvalConfig.from_cfg(cfg), float(cfg.driving_radar.frame_period_s)
    preds = calibrated_predictors(
        w, prediction_methods(ev, float(cfg.radar.frame_period_s),
                              LSTMPredictor.load(d / "train" / "model.pt")),
        json.loads((d / "calibration" / "models.json").read_text()),
        direct_path=d / "train_direct" / "model.pt", paths=d / "paths" / "paths.parquet",
        val=d / "windows" / "val.parquet", window=DatasetConfig.from_cfg(cfg).window,
        calibration=CalibrationConfig.from_cfg(cfg), cv_fit_points=ev.cv_fit_points,
        where="models.json", frame_periods_s=(dt, float(cfg.radar.frame_period_s)))
    return {k: v for k, v in preds.items() if k in wanted}


def study_assess(cfg, w: WarningConfig, d: Path, truth: pd.DataFrame, points: pd.DataFrame,
                 inputs: dict, preds: dict):
    """The safety stage's assessment (:func:`blindspot.safety.assess.assess`) of the scenes of
    ``truth`` (a part of the main draw; its first scene is the figure scene) on each input's
    tracks with ``preds`` and the warning settings ``w``; ``d``: data/ of a finished run."""
    group, _ = load_scenarios(cfg.scenario)
    return assess(truth, json.loads((d / "driving" / "scenes.json").read_text()), inputs, preds,
                  w, bodies=body_boxes(group), shape=EgoShape(group.ego.width_m,
                                                               group.ego.length_m),
                  points=points[["scene", "frame", "source"]],
                  frame_period_s=float(cfg.driving_radar.frame_period_s),
                  figure_scene=truth.scene.iloc[0], draw_seed=int(group.monte_carlo.seed),
                  ncap_inputs=())


def main(argv: list[str]) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=REPO / "data")
    ap.add_argument("--half", default="tuning", choices=("tuning", "held_out", "all"))
    ap.add_argument("--predictors", default="track_state,constant_velocity")
    ap.add_argument("--swap-velocity", type=float, default=None)
    ap.add_argument("--true-state", action="store_true")
    ap.add_argument("--velocity-lag", type=int, default=0, metavar="K",
                    help="with --true-state: each row's velocity from K frames earlier")
    ap.add_argument("--curve", action="store_true", help="print the operating characteristic")
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--warning", action="append", default=[], metavar="KEY=VALUE",
                    help="a warning-group setting for the decision (null: None)")
    ap.add_argument("--dissect", action="store_true",
                    help="what held the first predictor's decision back (tracker input)")
    ap.add_argument("overrides", nargs="*")
    args = ap.parse_args(argv)
    if args.velocity_lag < 0:
        ap.error(f"--velocity-lag: expected an integer >= 0 frames, found {args.velocity_lag}")
    if args.velocity_lag and not args.true_state:
        ap.error("--velocity-lag needs --true-state")
    cfg = OmegaConf.load(REPO / "params.yaml")
    tcfg = tracker_config(cfg, args.overrides)
    d = args.data
    truth = pd.read_parquet(d / "driving" / "truth.parquet")
    points = pd.read_parquet(d / "driving" / "points.parquet")
    mc = truth[truth.set == "monte_carlo"].scene.unique()
    half = replicate_half(mc)
    keep = {"tuning": mc[half], "held_out": mc[~half], "all": mc}[args.half]
    truth, points = truth[truth.scene.isin(keep)], points[points.scene.isin(keep)]
    if args.true_state:
        ts = true_state_tracks(truth)
        if args.velocity_lag:
            inputs = {"true_state": _late_velocity(ts, truth, args.velocity_lag)}
        else:
            inputs = {"true_state": ts}
    else:
        tracks, ego = tracked(truth, points, tcfg, args.jobs)
        settings = moving_test_settings(tcfg.moving)
        if args.swap_velocity is not None and settings["crossing_prior"] is not None:
            prior = settings["crossing_prior"]
            llr, _, _ = crossing_evidence(tracks, ego, prior)
            rows = (llr >= args.swap_velocity) & _young(tracks, prior.window) & tracks.moving
            tracks = crossing_state(tracks, ego, prior, rows.to_numpy(bool),
                                    tcfg.init_velocity_std_mps)
        inputs = {"tracker": tracks}
    for o in args.warning:
        k, eq, v = o.partition("=")
        if not eq or k not in cfg.warning:
            raise SystemExit(f"--warning {o!r}: expected KEY=VALUE with KEY one of "
                             f"{sorted(cfg.warning)}")
        cfg.warning[k] = yaml.safe_load(v)
    w = WarningConfig.from_cfg(cfg)
    preds = study_predictors(cfg, w, d, args.predictors.split(","))
    res = study_assess(cfg, w, d, truth, points, inputs, preds)
    print(f"{args.half} {'draw' if args.half == 'all' else 'half'}, {len(keep)} scenes; overrides {args.overrides}"
          + (f"; velocity swap at ln ratio {args.swap_velocity}" if args.swap_velocity else "")
          + ("; true state in line of sight" if args.true_state else "")
          + (f", velocity {args.velocity_lag} frames late" if args.velocity_lag else ""))
    block = ({} if args.half == "all"                     # the whole draw: no half's block
             else res.metrics.get("tuning_half" if args.half == "tuning" else "held_out_half", {}))
    for p in preds:
        m = {**res.metrics[p], **block.get(p, {})}
        for k in ("first_point_to_moving_s", "first_point_to_aeb_s"):   # the whole draw's
            m.setdefault(f"{k}_median", (m.get(k) or {}).get("median"))
        print(f"{p:18s} avoided after visible {m['avoided_after_visible_rate']:.3f}, false "
              f"activations {m['false_activation_rate']:.3f}, first point -> moving "
              f"{m.get('first_point_to_moving_s_median')} s, -> AEB "
              f"{m.get('first_point_to_aeb_s_median')} s")
        sc = res.scenes[res.scenes.intruding & (res.scenes.predictor == p)]
        per = sc.groupby("speed_kmh").agg(avoided=("avoided", "mean"),
                                          ttc_at_aeb_s=("aeb_lead_time_s", "median"))
        print(per.round(2).T.to_string())
        oc = res.curves[res.curves.predictor == p]
        best = {fa: oc.avoided_rate[oc.false_activation_rate <= fa].max() for fa in (0.03, 0.05, 0.1)}
        print("  operating characteristic (AEB threshold swept): most avoided at false activations "
              + ", ".join(f"<= {fa:.0%}: {v:.3f}" for fa, v in best.items()))
        if args.curve:
            print(oc[["threshold", "avoided_rate", "false_activation_rate"]].round(3)
                  .to_string(index=False))
    if args.dissect and not args.true_state:
        dissect(res, tracks, truth, points, ego, tcfg, next(iter(preds)))


if __name__ == "__main__":
    main(sys.argv[1:])
