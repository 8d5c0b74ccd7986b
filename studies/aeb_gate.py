"""The AEB gate (warning.aeb_gate) evaluated from the safety stage's risk rows, tuned on one half
of the Monte-Carlo scenes and reported on the other. Prints figures, asserts nothing.

    BLINDSPOT_SHARED=../shared .venv/bin/python studies/aeb_gate.py \
        [--data DIR] [--input tracker] [--json OUT] [--figure PNG]

Reads DIR/safety/risk.parquet (every predictor's p_collision and ttc_s per track row, the
safety stage's output), DIR/driving/truth.parquet and DIR/driving/scenes.json (DIR: ``data``),
and params.yaml (the warning group, the scenario bodies and ego). The braked outcome of a
request at every frame comes from :func:`blindspot.safety.assess.outcome_table`, so each
policy is a lookup; nothing is re-predicted.

Split (:func:`blindspot.safety.evaluation.replicate_half`): even replicates of each speed x
impact point x intruding cell tune (108 scenes), odd ones are held out (108). On the tuning
half, per predictor, for no gate and for stopping_time at each margin of --margins, the AEB
threshold is the one with the largest Youden index J = avoided rate - false-activation rate
(Youden 1950, Cancer 3(1); ties: lower mean impact speed, then the higher threshold), and the
margin is the one whose tuned point has the largest J (ties: lower impact speed, then the
smaller margin). ``--rule max_fa`` instead takes the most avoided collisions with at most
--max-fa false activations where any threshold gets there (issue 12's 1 % is 0 of the 54
non-intruding tuning scenes, so it often picks a point that brakes for almost nothing). The
held-out half is scored with the tuned settings, with the configured one (params.yaml:
warning.aeb_threshold, no gate) and with the configured threshold behind the gate at the
configured margin (warning.aeb_gate_margin_s); per speed: avoided rate, mean impact speed
(km/h), median AEB lead time (true TTC at the request, s) and false activations, with Wilson /
bootstrap intervals in --json. The warning is never gated, so its lead time does not change.

Diagnostics (they read the truth; not deployable settings): per predictor, the non-intruding
scenes whose risk reaches warning.aeb_threshold and whether their first such track follows a
true pedestrian (within 1 m) or none (clutter, e.g. on the parked cars); and
--pedestrian-tracks-only scores only the risk rows of tracks that follow a pedestrian, i.e.
the trigger policy once the tracker's clutter tracks are gone.

Conclusion: the stopping-time gate at 0.2 s with aeb_threshold 0.5 raises avoided minus false-
activation rate (Youden's J) on the held-out half for every moving predictor on every input;
held-out J 0.277 / 0.296 / 0.333 / 0.296 (CV / Kalman / scene LSTM / direct LSTM) against 0.259
/ 0.277 / 0.259 / 0.296 for the margins the tuning half picks: the configured gate stays
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
from omegaconf import OmegaConf

from blindspot.radar.scenario import load_scenarios
from blindspot.safety.config import WarningConfig
from blindspot.io import write_json
from blindspot.safety.assess import frame_risks, outcome_table
from blindspot.safety.braking import BrakingModel
from blindspot.safety.evaluation import (SceneInfo, aeb_gate_s, avoided_at_false_activation,
                                         operating_curve, replicate_half, scene_info,
                                         aeb_thresholds,
                                         scene_results, summarise)
from blindspot.safety.outcome import body_boxes
from blindspot.safety.risk import EgoShape

REPO = Path(__file__).resolve().parents[1]


def _subset(info: SceneInfo, keep: np.ndarray) -> SceneInfo:
    return SceneInfo(*(np.asarray(getattr(info, f))[keep] for f in SceneInfo.__dataclass_fields__))


def _best(curve: pd.DataFrame, max_fa: float | None) -> pd.Series:
    """The tuned point of an operating curve (module docstring): the largest Youden index
    J = avoided rate - false-activation rate, or with ``max_fa`` the most avoided collisions
    with at most max_fa false activations when any threshold gets there."""
    c = curve.assign(j=curve.avoided_rate - curve.false_activation_rate)
    ok = c[c.false_activation_rate <= max_fa + 1e-12] if max_fa is not None else c.iloc[:0]
    if len(ok):
        row = ok.sort_values(["avoided_rate", "impact_speed_kmh_mean", "threshold"],
                             ascending=[False, True, False]).iloc[0]
        return pd.concat([row, pd.Series({"rule": "max_fa"})])
    row = c.sort_values(["j", "impact_speed_kmh_mean", "threshold"],
                        ascending=[False, True, False]).iloc[0]
    return pd.concat([row, pd.Series({"rule": "youden"})])


def outcome_setup(truth: pd.DataFrame, meta: dict, bodies: dict, shape: EgoShape, w):
    """What the policy benchmarks score against, for the evaluated scenes of ``truth``: the
    braking model of ``w.aeb``, the outcome table (``sa``: scenes, ego speeds, frame times;
    ``impact`` (S, F + 1) km/h, NaN = avoided), the scenes' info and the tuning half (even
    replicates, :func:`replicate_half`)."""
    brakes = BrakingModel.from_config(w.aeb)
    sa, _, impact = outcome_table(truth, bodies, shape, brakes, w)
    return brakes, sa, impact, scene_info(truth, meta, sa.scenes), replicate_half(sa.scenes)


def half_results(rows: pd.DataFrame, setup: tuple, w) -> dict[str, pd.DataFrame]:
    """{"tune": .., "held_out": ..}: each half's scene results (:func:`scene_results`) of one
    predictor's risk ``rows`` behind the configured AEB gate and thresholds of ``w``;
    ``setup`` is :func:`outcome_setup`'s."""
    brakes, sa, impact, info, tune = setup
    p_w, p_aeb = frame_risks(rows, sa.scenes, sa.speed_mps, len(sa.time_s), brakes,
                             gate=w.aeb_gate, margin_s=w.aeb_gate_margin_s,
                             decision_delay_s=w.decision_delay_s)
    return {half: scene_results(p_w[m], _subset(info, m), impact[m], sa.time_s, p_aeb=p_aeb[m],
                                warning_threshold=w.warning_threshold,
                                decision_delay_s=w.decision_delay_s,
                                aeb_threshold=w.aeb_threshold)
            for half, m in (("tune", tune), ("held_out", ~tune))}


def half_counts(res: pd.DataFrame) -> dict[str, int]:
    """A half's scene results (:func:`half_results`) counted: intruding scenes avoided of
    intruding scenes, non-intruding scenes with an AEB request (false activations) of
    non-intruding scenes."""
    it = res.intruding.to_numpy()
    return {"n_avoided": int(res.avoided.to_numpy()[it].sum()), "n_intruding": int(it.sum()),
            "n_false": int((res.aeb_frame.to_numpy()[~it] >= 0).sum()),
            "n_non_intruding": int((~it).sum())}


def load_inputs(data: Path, input_name: str):
    """What the policy benchmarks read: (cfg = params.yaml, the typed warning group, the
    scenario group, bodies {name: (length, width, reference from front) m}, the ego's EgoShape,
    DATA/driving/truth.parquet (every set), DATA/driving/scenes.json, the safety stage's risk
    rows of ``input_name``)."""
    cfg = OmegaConf.load(REPO / "params.yaml")
    w = WarningConfig.from_cfg(cfg)
    group, _ = load_scenarios(cfg.scenario)
    bodies = body_boxes(group)
    shape = EgoShape(group.ego.width_m, group.ego.length_m)
    truth = pd.read_parquet(data / "driving/truth.parquet")
    meta = json.loads((data / "driving/scenes.json").read_text())
    risk = pd.read_parquet(data / "safety/risk.parquet")
    return cfg, w, group, bodies, shape, truth, meta, risk[risk.input == input_name]


def _nearest_pedestrian_m(rows: pd.DataFrame, truth: pd.DataFrame,
                          tracks: pd.DataFrame) -> pd.DataFrame:
    """rows + the track's position, speed and its distance to the nearest true pedestrian of
    that frame (m), with that pedestrian's behaviour; row order kept."""
    x = rows.reset_index(drop=True).reset_index().merge(
        tracks[["group", "frame", "track_id", "x_m", "y_m", "vx_mps", "vy_mps"]],
        on=["group", "frame", "track_id"], how="left")
    tp = truth[["scene", "frame", "behaviour", "x_m", "y_m"]].rename(
        columns={"scene": "group", "x_m": "px", "y_m": "py"})
    m = x.merge(tp, on=["group", "frame"], how="left")
    m["distance_m"] = np.hypot(m.x_m - m.px, m.y_m - m.py)
    m = m.sort_values(["index", "distance_m"]).drop_duplicates("index").sort_values("index")
    m["speed_mps"] = np.hypot(m.vx_mps, m.vy_mps)
    return m.drop(columns=["index", "px", "py"]).reset_index(drop=True)


def trigger_causes(risk: pd.DataFrame, truth: pd.DataFrame, tracks: pd.DataFrame,
                   threshold: float, kind: str = "non", near_m: float = 1.0) -> pd.DataFrame:
    """Per non-intruding (``kind = "non"``) or intruding (``"int"``) scene whose risk reaches
    ``threshold`` (ungated): the row that requests AEB (its first such row), its predicted TTC,
    track speed, and the distance from that track to the nearest true pedestrian (a track
    farther than ``near_m`` follows no pedestrian: clutter)."""
    non = risk[risk.group.str.contains(f"_{kind}_") & (risk.p_collision >= threshold)]
    first = non.sort_values(["group", "frame", "p_collision"], ascending=[True, True, False]) \
        .drop_duplicates("group")
    m = _nearest_pedestrian_m(first, truth, tracks)
    m["follows_pedestrian"] = m.distance_m <= near_m
    return m[["group", "frame", "p_collision", "ttc_s", "speed_mps", "distance_m",
              "follows_pedestrian", "behaviour"]]


def _figure(path: Path, curves: dict) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(curves), figsize=(3.2 * len(curves), 3.2), sharey=True)
    for ax, (name, cs) in zip(np.atleast_1d(axes), curves.items()):
        for label, c in cs.items():
            ax.plot(c.false_activation_rate, c.avoided_rate, ".-", ms=3, label=label)
        ax.set_title(name, fontsize=9)
        ax.set_xlabel("false activations (held out)")
        ax.set_xlim(0, 1)
        ax.set_ylim(0, 1)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="lower right")
    np.atleast_1d(axes)[0].set_ylabel("avoided collisions (held out)")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def _none_nan(x) -> float | None:
    return None if pd.isna(x) else float(x)


def main(argv: list[str]) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=REPO / "data")
    ap.add_argument("--input", default="tracker")
    ap.add_argument("--margins", default="0,0.1,0.2,0.3,0.4,0.5,0.6,0.8,1.0,1.5")
    ap.add_argument("--rule", choices=("youden", "max_fa"), default="youden")
    ap.add_argument("--max-fa", type=float, default=0.01,
                    help="with --rule max_fa: largest false-activation rate on the tuning half "
                         "(issue 12: 1 %%)")
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument("--pedestrian-tracks-only", action="store_true",
                    help="diagnostic, uses the truth: score only the risk rows of tracks within "
                         "1 m of a true pedestrian (what the trigger policy does once the "
                         "tracker's clutter tracks are gone); not a deployable setting")
    ap.add_argument("--figure", type=Path, default=None,
                    help="PNG of the held-out operating curves, ungated and gated")
    args = ap.parse_args(argv)
    cfg, w, group, bodies, shape, truth_all, meta, risk = load_inputs(args.data, args.input)
    truth = truth_all[truth_all.set == "monte_carlo"]
    tracks = pd.read_parquet(args.data / "driving/tracks.parquet") if args.input == "tracker" \
        else None
    if args.pedestrian_tracks_only:
        if tracks is None:
            raise SystemExit("--pedestrian-tracks-only needs --input tracker")
        risk = risk[(_nearest_pedestrian_m(risk, truth, tracks).distance_m <= 1.0).to_numpy()]
        print(f"DIAGNOSTIC: only the {len(risk)} risk rows of tracks within 1 m of a true "
              "pedestrian are scored")
    main_brakes, sa, impact, info, tune = outcome_setup(truth, meta, bodies, shape, w)
    F = len(sa.time_s)
    halves = {"tune": tune, "held_out": ~tune}
    thresholds = aeb_thresholds(w.n_thresholds, w.tail_thresholds)
    margins = sorted({float(m) for m in args.margins.split(",")} | {w.aeb_gate_margin_s})
    print(f"{len(sa.scenes)} scenes ({tune.sum()} tune / {(~tune).sum()} held out), input "
          f"{args.input}; gate TTC_stop + decision delay {w.decision_delay_s} s + margin at "
          + ", ".join(f"{v:g} km/h: {g:.3f} s" for v, g in
                      zip(sorted(set(info.speed_kmh)),
                          main_brakes.stop_ttc(np.array(sorted(set(info.speed_kmh))) / 3.6))))
    kw = dict(warning_threshold=w.warning_threshold, decision_delay_s=w.decision_delay_s)
    report: dict = {"split": "replicate_half (even replicates tune, odd held out)",
                    "input": args.input, "rule": args.rule,
                    "max_fa_tune": args.max_fa if args.rule == "max_fa" else None,
                    "pedestrian_tracks_only": args.pedestrian_tracks_only, "predictors": {}}
    fig_curves: dict = {}
    for name in risk.predictor.unique():          # four predictors
        rows = risk[risk.predictor == name]
        variants = {("none", 0.0): frame_risks(rows, sa.scenes, sa.speed_mps, F, main_brakes,
                                               gate="none", margin_s=0.0,
                                               decision_delay_s=w.decision_delay_s)}
        for m in margins:                          # a handful of candidate margins
            variants[("stopping_time", m)] = frame_risks(
                rows, sa.scenes, sa.speed_mps, F, main_brakes, gate="stopping_time",
                margin_s=m, decision_delay_s=w.decision_delay_s)
        tuned: dict = {}
        for (gate, m), (_, p_aeb) in variants.items():
            c = operating_curve(p_aeb[tune], _subset(info, tune), impact[tune], thresholds,
                                sa.time_s)
            tuned[(gate, m)] = _best(c, args.max_fa if args.rule == "max_fa" else None)
        pick = {}
        for gate in ("none", "stopping_time"):
            cand = [(k, b) for k, b in tuned.items() if k[0] == gate]
            ok = [(k, b) for k, b in cand if b["rule"] == "max_fa"]
            if ok:                                 # the FA bound holds: most avoided
                pick[gate] = sorted(ok, key=lambda kb: (-kb[1].avoided_rate,
                                                        kb[1].impact_speed_kmh_mean,
                                                        kb[0][1]))[0]
            else:                                  # it never holds: largest Youden J
                pick[gate] = sorted(cand, key=lambda kb: (-kb[1].j, kb[1].impact_speed_kmh_mean,
                                                          kb[0][1]))[0]
        out = {"tuning_rule": ", ".join(
            f"{g}: " + ("most avoided with FA <= %g" % args.max_fa if b["rule"] == "max_fa"
                        else "largest Youden J") for g, (_, b) in pick.items())}
        settings = [("configured", ("none", 0.0), w.aeb_threshold),
                    ("configured_gated", ("stopping_time", w.aeb_gate_margin_s), w.aeb_threshold)]
        settings += [(f"tuned_{g}", k, float(b.threshold)) for g, (k, b) in pick.items()]
        for label, key, thr in settings:
            p_w, p_aeb = variants[key]
            entry = {"gate": key[0], "margin_s": key[1], "aeb_threshold": thr}
            for half, keep in halves.items():
                res = scene_results(p_w[keep], _subset(info, keep), impact[keep],
                                    sa.time_s, aeb_threshold=thr, p_aeb=p_aeb[keep], **kw)
                s = summarise(res, n_bootstrap=w.n_bootstrap, seed=w.seed)
                entry[half] = {
                    "avoided_rate": s["avoided_rate"], "avoided_rate_ci95": s["avoided_rate_ci95"],
                    "false_activation_rate": s["false_activation_rate"],
                    "false_activation_rate_ci95": s["false_activation_rate_ci95"],
                    "by_speed_kmh": {k: {kk: v[kk] for kk in (
                        "avoided_rate", "impact_speed_kmh_mean", "aeb_lead_time_s_median",
                        "lead_time_s_median", "false_activation_rate")}
                        for k, v in s["by_speed_kmh"].items()},
                    "goals": s["goals"]}
            out[label] = entry
        # the held-out operating curve of each gate at its tuned margin
        for gate, (key, _) in pick.items():
            c = operating_curve(variants[key][1][~tune], _subset(info, ~tune), impact[~tune],
                                thresholds, sa.time_s)
            out[f"tuned_{gate}"]["held_out_curve"] = c.round(4).to_dict(orient="list")
            out[f"tuned_{gate}"]["held_out_avoided_at_fa"] = avoided_at_false_activation(
                c, (0.1, 0.2, 0.3))
            fig_curves.setdefault(name, {})[
                "no gate" if gate == "none" else f"gate, margin {key[1]:g} s"] = c
        if tracks is not None:                     # why the false activations happen
            fa = trigger_causes(rows, truth, tracks, w.aeb_threshold)
            hit = trigger_causes(rows, truth, tracks, w.aeb_threshold, kind="int")
            res = scene_results(*variants[("none", 0.0)][:1], info, impact, sa.time_s,
                                aeb_threshold=w.aeb_threshold, **kw)
            hit = hit.merge(res[["scene", "avoided"]], left_on="group", right_on="scene")
            gi = pd.Index(sa.scenes).get_indexer(rows.group)
            g = aeb_gate_s(np.where(gi >= 0, sa.speed_mps[gi], 0.0), main_brakes,
                           gate="stopping_time", margin_s=w.aeb_gate_margin_s,
                           decision_delay_s=w.decision_delay_s)
            fa_g = trigger_causes(rows[(rows.ttc_s.to_numpy() <= g)], truth, tracks,
                                  w.aeb_threshold)
            out["false_activation_causes"] = {
                "aeb_threshold": w.aeb_threshold, "n_scenes": int(len(fa)),
                "n_track_on_no_pedestrian": int((~fa.follows_pedestrian).sum()),
                "ttc_s_median": _none_nan(fa.ttc_s.median()),
                "speed_mps_median_no_pedestrian": _none_nan(
                    fa.speed_mps[~fa.follows_pedestrian].median()),
                "behaviour_of_followed": fa.behaviour[fa.follows_pedestrian]
                .value_counts().to_dict(),
                "intruding_avoided": int(hit.avoided.sum()),
                "intruding_avoided_by_track_on_no_pedestrian": int(
                    (hit.avoided & ~hit.follows_pedestrian).sum()),
                "gated": {"margin_s": w.aeb_gate_margin_s, "n_scenes": int(len(fa_g)),
                          "n_track_on_no_pedestrian": int((~fa_g.follows_pedestrian).sum()),
                          "ttc_s_median": _none_nan(fa_g.ttc_s.median())}}
        report["predictors"][name] = out
        print(f"\n== {name}")
        print(f"  tuning rule: {out['tuning_rule']}")
        for label, e in out.items():
            if label == "tuning_rule":
                continue
            if label == "false_activation_causes":
                print(f"  false activations at threshold {e['aeb_threshold']} (all scenes, "
                      f"ungated): {e['n_scenes']} scenes, first AEB-level track on no "
                      f"pedestrian (> 1 m) in {e['n_track_on_no_pedestrian']} (median speed "
                      f"{e['speed_mps_median_no_pedestrian']} m/s), median predicted TTC "
                      f"{e['ttc_s_median']} s; pedestrians followed: "
                      f"{e['behaviour_of_followed']}; of the {e['intruding_avoided']} avoided "
                      "intruding scenes (ungated), "
                      f"{e['intruding_avoided_by_track_on_no_pedestrian']} were braked first for "
                      "a track on no pedestrian; behind the gate at "
                      f"{e['gated']['margin_s']:g} s: {e['gated']['n_scenes']} false "
                      f"activations, {e['gated']['n_track_on_no_pedestrian']} by a track on no "
                      f"pedestrian, median predicted TTC {e['gated']['ttc_s_median']} s")
                continue
            h = e["held_out"]
            print(f"  {label:22s} gate {e['gate']:13s} margin {e['margin_s']:.2f} s thr "
                  f"{e['aeb_threshold']:.2f} | tune avoided {e['tune']['avoided_rate']:.3f} FA "
                  f"{e['tune']['false_activation_rate']:.3f} | HELD OUT avoided "
                  f"{h['avoided_rate']:.3f} {np.round(h['avoided_rate_ci95'], 3).tolist()} FA "
                  f"{h['false_activation_rate']:.3f} "
                  f"{np.round(h['false_activation_rate_ci95'], 3).tolist()}")
            print("      held out by speed (avoided / impact km/h / AEB lead s / FA): " + "; ".join(
                f"{k}: {v['avoided_rate']:.2f}/{v['impact_speed_kmh_mean']:.1f}/"
                f"{(v['aeb_lead_time_s_median'] or float('nan')):.2f}/"
                f"{v['false_activation_rate']:.2f}"
                for k, v in h["by_speed_kmh"].items()))
            if "held_out_avoided_at_fa" in e:
                print("      held-out curve, most avoided at FA <= 0.1/0.2/0.3: "
                      + "/".join("-" if v is None else f"{v:.2f}"
                                 for v in e["held_out_avoided_at_fa"].values()))
    if args.json:
        write_json(args.json, report)
    if args.figure:
        _figure(args.figure, fig_curves)


if __name__ == "__main__":
    main(sys.argv[1:])
