"""Clutter tracks on the parked cars: candidate causal moving-object tests evaluated from the
safety stage's risk rows, tuned on one half of the Monte-Carlo scenes and reported on the other.
Prints figures, asserts nothing.

    BLINDSPOT_SHARED=../shared .venv/bin/python studies/clutter.py \
        [--data DIR] [--json OUT] [--cell M] [--lags L1,L2] [--window N]

DIR (default ``data``) must hold a driving_track + safety run with the grid off
(tracker.moving.static_evidence_min = 0, as the 2026-11-30 repro in /work/main/data): the
benchmark removes rows from that run's risk rows and refuses tracks whose moving flag already
left them out.

A stricter moving test only removes track rows, so the tracker input's risk rows
(DIR/safety/risk.parquet) of the rows it keeps give the new outcomes; nothing is re-predicted
(aeb_gate's machinery: :func:`blindspot.safety.assess.outcome_table`, the configured AEB
gate warning.aeb_gate at warning.aeb_gate_margin_s, :func:`blindspot.safety.evaluation
.replicate_half`: even replicates tune, odd ones are held out).

Candidates, each a per-row score from what the car has at that frame (no truth):

- ``static_evidence``: a static-environment evidence grid (Werber et al. 2015, "Automotive radar
  gridmap representations", IEEE ICMIM): every radar point the ego-motion Doppler test calls
  static (points.parquet ``static``) is accumulated in the world frame in cells of
  ``--cell`` m; a track row's score is the number of static points of frames f - ``lag`` and
  earlier within the 3 x 3 cells around its position, a coasting row taking its track's last
  measured row's score (:func:`blindspot.track.moving.last_hit_rows`, as the stage). A row
  whose score reaches k is clutter.
- ``displacement``: the track's net displacement over its last ``--window`` rows over the path
  its filtered velocity integrates over them (a cluster sliding on a car face moves much less
  than its velocity says); a row below r is clutter.

Each rule keeps a row only if the track is classed moving (the stage's ``moving`` flag) and the
rule does not call it clutter. Per predictor (the tracker input) the rule's threshold is the one
with the largest Youden J = avoided rate - false-activation rate on the tuning half at the
configured AEB threshold behind the configured gate; the held-out half is reported at that
threshold beside the stage's own moving test. The configured rule (params.yaml
tracker.moving.static_*) is reported the same way, with the held-out intruding scenes it stops
avoiding and how many of those the grid-off run braked first for a clutter track (luck). Also printed: intruding scenes whose lead
pedestrian is never classed moving (truth labels, stages/driving_track.confusion; today 20 of
108), and the causes of the false activations left (first AEB-level track within 1 m of a true
pedestrian or not; aeb_gate.trigger_causes).

Conclusion: the static evidence grid, cell 0.5 m, lag 10, >= 1 hit, removes the clutter tracks
on the parked cars: held-out J 0.167 / 0.148 / 0.167 (grid off) -> 0.278 / 0.296 / 0.333 (CV /
Kalman / scene LSTM); no other cell x lag pair does better held out (conf/warning/default.yaml
moving_static_evidence_*, docs/studies/safety.md).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads
import numpy as np
import pandas as pd

REPO = Path(__file__).resolve().parents[1]

from aeb_gate import half_results, load_inputs, outcome_setup, trigger_causes  # noqa: E402
from blindspot.track.config import TrackerConfig  # noqa: E402
from blindspot.io import write_json  # noqa: E402
from blindspot.safety.assess import frame_risks  # noqa: E402
from blindspot.safety.evaluation import (aeb_gate_s, replicate_half,  # noqa: E402
                                         scene_results, summarise)
from blindspot.track.moving import (moving_frames, moving_test_settings,  # noqa: E402
                                    moving_tracks, track_static_evidence)


def displacement_ratio(tracks: pd.DataFrame, window: int) -> np.ndarray:
    """(N,) per row: |x_t - x_{t-window}| / sum of |v| dt over the same rows (NaN for the first
    ``window`` rows of a track). tracks sorted by group, track_id, frame."""
    g = (tracks.group + "\x00" + tracks.track_id.astype(str)).to_numpy()
    x, y = tracks.x_m.to_numpy(), tracks.y_m.to_numpy()
    t = tracks.time_s.to_numpy()
    sp = np.hypot(tracks.vx_mps.to_numpy(), tracks.vy_mps.to_numpy())
    same = np.r_[False, g[1:] == g[:-1]]
    dt = np.where(same, np.r_[0.0, np.diff(t)], 0.0)
    path = np.cumsum(sp * dt)
    out = np.full(len(tracks), np.nan)
    i = np.arange(len(tracks))
    j = i - window
    ok = (j >= 0)
    ok[ok] = g[j[ok]] == g[ok]
    net = np.hypot(x[ok] - x[j[ok]], y[ok] - y[j[ok]])
    integ = path[ok] - path[j[ok]]
    out[ok] = net / np.maximum(integ, 1e-6)
    return out


def persistence(tracks: pd.DataFrame, ego: pd.DataFrame, mv, window: int) -> np.ndarray:
    """(N,) per row: the most rows, among any ``window`` consecutive rows of the track so far,
    whose own frame passes the stage's moving test unlatched (fast, chi-square, and the summed
    Doppler log-likelihood ratio above its bound); an M-of-N confirmation of the moving class
    (Blackman & Popoli 1999, sec. 6.2, as for track confirmation). tracks sorted by group,
    track_id, frame."""
    inst = moving_frames(tracks, ego=ego, **moving_test_settings(mv, grid=False))
    key = (tracks.group + "\x00" + tracks.track_id.astype(str)).to_numpy()
    roll = pd.Series(inst.astype(float)).groupby(key, sort=False).rolling(
        window, min_periods=1).sum().to_numpy()
    return pd.Series(roll).groupby(key, sort=False).cummax().to_numpy()


def main(argv: list[str]) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=REPO / "data")
    ap.add_argument("--cell", type=float, default=0.5)
    ap.add_argument("--lags", default="1,3,5,10")
    ap.add_argument("--window", type=int, default=5)
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args(argv)
    cfg, w, _, bodies, shape, truth_all, meta, risk = load_inputs(args.data, "tracker")
    mv = TrackerConfig.from_cfg(cfg).moving
    truth = truth_all[truth_all.set == "monte_carlo"]
    tracks = pd.read_parquet(args.data / "driving/tracks.parquet")
    tracks = tracks.sort_values(["group", "track_id", "frame"]).reset_index(drop=True)
    points = pd.read_parquet(args.data / "driving/points.parquet")

    from blindspot.synth.driving_tracks import confusion, track_labels
    labels = track_labels(tracks, points, TrackerConfig.from_cfg(cfg).cluster_eps_m)

    ego = (truth_all.groupby(["scene", "frame"], as_index=False)
           [["ego_x_m", "ego_y_m", "ego_yaw_deg"]].first().rename(columns={"scene": "group"}))
    scores: dict[str, tuple[np.ndarray, np.ndarray, str]] = {}
    for lag in (int(v) for v in args.lags.split(",")):           # as the stage reads it
        ev = track_static_evidence(tracks, points, cell_m=args.cell, lag_frames=lag)
        scores[f"static_evidence cell {args.cell:g} m lag {lag}"] = (
            ev, np.array([1, 2, 3, 5, 8, 12, 20, 30, 50, 80, 120]), "ge")
    scores[f"moving test M of {args.window} rows"] = (
        persistence(tracks, ego, mv, args.window), np.arange(2, args.window + 1), "lt")
    key_t = (tracks.group + "\x00" + tracks.track_id.astype(str)).to_numpy()
    age = pd.Series(tracks.confirmed.to_numpy(float)).groupby(key_t, sort=False).cumsum()
    scores["confirmed age (rows)"] = (age.to_numpy(), np.array([2, 3, 5, 8, 10, 15]), "lt")
    dr = displacement_ratio(tracks, args.window)
    scores[f"displacement window {args.window}"] = (
        dr, np.array([0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7]), "lt")

    setup = outcome_setup(truth, meta, bodies, shape, w)
    main_brakes, sa, impact, info, tune = setup
    F = len(sa.time_s)
    kw = dict(warning_threshold=w.warning_threshold, decision_delay_s=w.decision_delay_s,
              aeb_threshold=w.aeb_threshold)
    key = ["group", "frame", "track_id"]
    moving = tracks.moving.to_numpy(bool)
    without_grid = moving_tracks(tracks, ego=ego, **moving_test_settings(mv, grid=False))
    if not np.array_equal(moving, without_grid):
        raise SystemExit(f"{args.data / 'driving/tracks.parquet'}: its moving flag is not the "
                         "moving test without the static-evidence grid (was driving_track run "
                         "with tracker.moving.static_evidence_min > 0?); this benchmark needs "
                         "the risk rows of a run with the grid off, e.g. the data/ of "
                         "`dvc exp run -S tracker.moving.static_evidence_min=0`")
    import time
    t0 = time.process_time()
    conf_ev = track_static_evidence(tracks, points, cell_m=mv.static_cell_m,
                                    lag_frames=mv.static_lag_frames) \
        if mv.static_evidence_min > 0 else np.zeros(len(tracks), int)
    cpu = time.process_time() - t0
    n_frames = tracks[["group", "frame"]].drop_duplicates().shape[0]
    print(f"static_evidence (configured) on {len(tracks)} track rows, {int(points.static.sum())} "
          f"static points, {n_frames} scene-frames: {cpu:.2f} s CPU (process_time), "
          f"{1e3 * cpu / n_frames:.3f} ms per frame")
    conf_name = (f"CONFIGURED static_evidence cell {mv.static_cell_m:g} m lag "
                 f"{mv.static_lag_frames} >= {mv.static_evidence_min}")

    def evaluate(rows: pd.DataFrame):
        out = {}
        for half, res in half_results(rows, setup, w).items():
            s = summarise(res, n_bootstrap=w.n_bootstrap, seed=w.seed)
            out[half] = {k: s[k] for k in ("avoided_rate", "avoided_rate_ci95",
                                            "false_activation_rate",
                                            "false_activation_rate_ci95")}
            out[half]["n_avoided"] = int(res.avoided[res.intruding].sum())
            out[half]["n_intruding"] = int(res.intruding.sum())
            out[half]["n_false"] = int(round(s["false_activation_rate"]
                                             * (~res.intruding).sum()))
            out[half]["n_non_intruding"] = int((~res.intruding).sum())
        return out

    report: dict = {"input": "tracker", "aeb_threshold": w.aeb_threshold,
                    "aeb_gate": w.aeb_gate, "aeb_gate_margin_s": w.aeb_gate_margin_s,
                    "rules": {}}
    base_missed = confusion(tracks, moving, labels, truth_all)
    lab = labels.reindex(pd.MultiIndex.from_frame(tracks[["group", "track_id"]])).to_numpy()
    ped = pd.notna(lab) & (lab != "static")
    kept = moving & ~((conf_ev >= mv.static_evidence_min)
                      & (mv.static_evidence_min > 0))
    print(f"moving rows (truth labels, all scenes): pedestrian tracks {int((moving & ped).sum())}"
          f" -> {int((kept & ped).sum())}, static-world tracks {int((moving & ~ped).sum())} -> "
          f"{int((kept & ~ped).sum())} with the configured grid")
    print(f"{len(sa.scenes)} scenes ({tune.sum()} tune / {(~tune).sum()} held out); AEB "
          f"threshold {w.aeb_threshold} behind gate {w.aeb_gate} +{w.aeb_gate_margin_s} s")
    print(f"stage's moving test: static-world tracks classed moving "
          f"{base_missed['static_world_moving']} of {base_missed['static_world_tracks']}; lead "
          f"pedestrian never moving {base_missed['intruding_scenes_missed']} of "
          f"{base_missed['intruding_scenes']} intruding scenes")
    for name in ("constant_velocity", "kalman", "lstm"):
        rows = risk[risk.predictor == name]
        if not len(rows):
            continue
        m = rows[key].merge(tracks[key].assign(_i=np.arange(len(tracks))), on=key, how="left")
        idx = m._i.to_numpy()
        base = evaluate(rows)
        fa0 = trigger_causes(rows, truth, tracks, w.aeb_threshold)
        print(f"\n== {name}: stage's moving test | tune avoided "
              f"{base['tune']['avoided_rate']:.3f} FA {base['tune']['false_activation_rate']:.3f}"
              f" | HELD OUT avoided {base['held_out']['avoided_rate']:.3f} "
              f"{np.round(base['held_out']['avoided_rate_ci95'], 3).tolist()} FA "
              f"{base['held_out']['false_activation_rate']:.3f} "
              f"{np.round(base['held_out']['false_activation_rate_ci95'], 3).tolist()}"
              f" | ungated triggers on non-intruding (all): {len(fa0)}, clutter "
              f"{int((~fa0.follows_pedestrian).sum())}")
        entry = {"stage_moving_test": base, "candidates": {}}
        # the configured rule (params.yaml), paired with the stage's test on the same scenes
        drop = (conf_ev[idx] >= mv.static_evidence_min) \
            if mv.static_evidence_min > 0 else np.zeros(len(rows), bool)
        e = evaluate(rows[~drop])
        c = confusion(tracks, moving & ~((conf_ev >= mv.static_evidence_min)
                                         & (mv.static_evidence_min > 0)),
                      labels, truth_all)
        held = ~tune
        r0 = scene_results(*frame_risks(rows, sa.scenes, sa.speed_mps, F, main_brakes,
                                        gate=w.aeb_gate, margin_s=w.aeb_gate_margin_s,
                                        decision_delay_s=w.decision_delay_s)[:1], info, impact,
                           sa.time_s, p_aeb=frame_risks(
                               rows, sa.scenes, sa.speed_mps, F, main_brakes, gate=w.aeb_gate,
                               margin_s=w.aeb_gate_margin_s,
                               decision_delay_s=w.decision_delay_s)[1], **kw)
        pw1, pa1 = frame_risks(rows[~drop], sa.scenes, sa.speed_mps, F, main_brakes,
                               gate=w.aeb_gate, margin_s=w.aeb_gate_margin_s,
                               decision_delay_s=w.decision_delay_s)
        r1 = scene_results(pw1, info, impact, sa.time_s, p_aeb=pa1, **kw)
        lost = r0.intruding & r0.avoided & ~r1.avoided & held
        gained = r0.intruding & ~r0.avoided & r1.avoided & held
        # who braked the lost ones under the stage's test: the first AEB row behind the gate
        gi = pd.Index(sa.scenes).get_indexer(rows.group)
        g = aeb_gate_s(np.where(gi >= 0, sa.speed_mps[gi], 0.0), main_brakes, gate=w.aeb_gate,
                       margin_s=w.aeb_gate_margin_s, decision_delay_s=w.decision_delay_s)
        gated = rows[rows.ttc_s.to_numpy() <= g] if w.aeb_gate != "none" else rows
        hit = trigger_causes(gated, truth, tracks, w.aeb_threshold, kind="int")
        by_clutter = set(hit.group[~hit.follows_pedestrian])
        n_lost_clutter = int(sum(sc in by_clutter for sc in sa.scenes[lost.to_numpy()]))
        j0 = base["held_out"]["avoided_rate"] - base["held_out"]["false_activation_rate"]
        j1 = e["held_out"]["avoided_rate"] - e["held_out"]["false_activation_rate"]
        h = e["held_out"]
        print(f"  {conf_name} | HELD OUT avoided {h['avoided_rate']:.3f} "
              f"{np.round(h['avoided_rate_ci95'], 3).tolist()} ({h['n_avoided']}/"
              f"{h['n_intruding']}) FA {h['false_activation_rate']:.3f} "
              f"{np.round(h['false_activation_rate_ci95'], 3).tolist()} ({h['n_false']}/"
              f"{h['n_non_intruding']}) | J {j0:.3f} -> {j1:.3f} | held-out avoided lost "
              f"{int(lost.sum())} (first braked for a clutter track: {n_lost_clutter}), gained "
              f"{int(gained.sum())} | static-world tracks moving {c['static_world_moving']} | "
              f"lead ped never moving {c['intruding_scenes_missed']}/{c['intruding_scenes']}")
        entry["configured"] = {**e, "held_out_j_stage": j0, "held_out_j": j1,
                               "held_out_avoided_lost": int(lost.sum()),
                               "held_out_avoided_lost_clutter_braked": n_lost_clutter,
                               "held_out_avoided_gained": int(gained.sum()),
                               "static_world_moving": c["static_world_moving"],
                               "intruding_scenes_missed": c["intruding_scenes_missed"]}
        for sname, (score, grid, how) in scores.items():
            s = score[idx]
            best = None
            for thr in grid:
                clutter = (s >= thr) if how == "ge" else (s < thr)
                e = evaluate(rows[~clutter])
                j = e["tune"]["avoided_rate"] - e["tune"]["false_activation_rate"]
                if best is None or j > best[0] + 1e-12:
                    best = (j, thr, e, clutter)
            j, thr, e, clutter = best
            cl_all = (score >= thr) if how == "ge" else (score < thr)
            mv = moving & ~np.nan_to_num(cl_all, nan=0).astype(bool)
            c = confusion(tracks, mv, labels, truth_all)
            fa = trigger_causes(rows[~clutter], truth, tracks, w.aeb_threshold)
            h = e["held_out"]
            print(f"  {sname:38s} tuned {'>=' if how == 'ge' else '<'} {thr:g} (tune J {j:.3f})"
                  f" | HELD OUT avoided {h['avoided_rate']:.3f} "
                  f"{np.round(h['avoided_rate_ci95'], 3).tolist()} FA "
                  f"{h['false_activation_rate']:.3f} "
                  f"{np.round(h['false_activation_rate_ci95'], 3).tolist()} | static-world moving "
                  f"{c['static_world_moving']} | lead ped never moving "
                  f"{c['intruding_scenes_missed']}/{c['intruding_scenes']} | ungated triggers "
                  f"non-intruding {len(fa)}, clutter {int((~fa.follows_pedestrian).sum())}")
            entry["candidates"][sname] = {
                "threshold": float(thr), "tune_j": float(j), **e,
                "static_world_moving": c["static_world_moving"],
                "intruding_scenes_missed": c["intruding_scenes_missed"],
                "ungated_false_triggers": int(len(fa)),
                "ungated_false_triggers_clutter": int((~fa.follows_pedestrian).sum())}
        report["rules"][name] = entry
    if args.json:
        write_json(args.json, report)


if __name__ == "__main__":
    main(sys.argv[1:])
