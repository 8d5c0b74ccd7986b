"""Where the time goes between the lead pedestrian's first radar point and the first track the
decision assesses (issue 40), for tracker settings given as overrides. Prints figures, asserts
nothing.

    BLINDSPOT_SHARED=../shared PYTHONPATH=src .venv/bin/python studies/first_point.py \
        [--data data] [--half tuning|held_out|all] [--criteria] [--born-behind] \
        [tracker overrides key=value ...]

On the intruding Monte-Carlo scenes of one half (even replicates tune, odd are held out), per
scene: the time of the lead pedestrian's first radar point (truth label; scoring only), of the
first track row within 1 m of its true position, the first confirmed one, the first moving one
(the tracker's moving-object test, tracker.moving), each as a delay after the first point
(median, p90, per speed). On the non-intruding scenes of the same half, and on the intruding
ones, the confirmed tracks classed moving that are static-world clutter (no pedestrian point
within the cluster radius over their life: driving_track's labels): the price of seeing early.
Overrides: e.g. init_doppler_std_mps=0.3 doppler_confirm_log_ratio=4.6
moving.doppler_first_log_ratio=4.6. Time: about 20 s for the whole main draw (``--half all``).

``--criteria``: at the lead child's first confirmed track row within 1 m of it, how many are
classed moving, and for the others what each path of the moving test (tracker.moving) read
there against its threshold: the filtered speed, the chi-square test, the approach test's z,
the Doppler-first ratio, the Doppler refutation sum and the crossing prior's ratio, with the
filtered velocity beside the true one.

``--born-behind``: the share of the confirmed tracks (the lead child's, other pedestrians', the
static world's; driving_track's labels) born where static points of the last
:data:`BEHIND_FRAMES` frames lay nearer the radar (by :data:`BEHIND_MARGIN_M` or more) within
:data:`BEHIND_WIDTH_M` across the line of sight to the birth: tracks stepping out of a static
object's shadow, the context an occlusion prior would read.

Conclusion (2026-12-06, main draw, docs/studies/first-point-to-brake.md, ninth pass): the
track confirms 0.2 s after the child's first point; with the crossing threshold at ln 1.0, 55 of
108 children were classed moving on their first confirmed row and for the other 53 no path
passed (filtered crossing speed -0.69 m/s against the true -1.38, approach z 0.76 against 1.28,
radial speeds static-looking), so the median first point -> moving sits on the 0.2 / 0.3 s frame
boundary; at ln 0.01 (taken) 62 of 108. The child's tracks are born behind static points about
as often as the static world's (about a fifth of each): no occlusion prior from these points.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads
import numpy as np
import pandas as pd
import yaml
from omegaconf import OmegaConf
from scipy.stats import chi2, norm

from blindspot.track.config import TrackerConfig
from blindspot.safety.evaluation import delay_stats, first_track_times, replicate_half
from blindspot.synth.driving_tracks import track_labels, tracker_input
from blindspot.track.config import MovingConfig
from blindspot.track.crossing import approach_z, crossing_evidence
from blindspot.track.moving import (DOPPLER_FIRST_WINDOW, doppler_evidence,
                                    doppler_motion_evidence, moving_test_settings, moving_tracks,
                                    velocity_chi2)
from blindspot.track.tracker import track_points

REPO = Path(__file__).resolve().parents[1]
BEHIND_FRAMES = 5       # frames of static points before a track's birth that may hide it
BEHIND_WIDTH_M = 0.4    # m across the line of sight within which a static point hides a birth
BEHIND_MARGIN_M = 0.5   # m nearer the radar than the birth a hiding static point must lie


def _typed(v: str):
    """A command-line value as YAML reads it: 2 an int, 2.0 a float, null (or none) None; a
    string that is a number YAML 1.1 does not read as one (1e-3) a float."""
    if v.lower() == "none":
        return None
    out = yaml.safe_load(v)
    if isinstance(out, str):
        try:
            return float(out)
        except ValueError:
            return out
    return out


def tracker_config(cfg, overrides: list[str]) -> TrackerConfig:
    """params.yaml's tracker settings with ``key=value`` overrides (``moving.<key>`` for the
    moving test; ``null`` for None), checked as the stage checks them."""
    tcfg = TrackerConfig.from_cfg(cfg)
    mv = dataclasses.asdict(tcfg.moving)
    top = {}
    for o in overrides:
        k, v = o.split("=", 1)
        if k.startswith("moving."):
            mv[k[7:]] = _typed(v)
        else:
            top[k] = _typed(v)
    return dataclasses.replace(tcfg, **top, moving=MovingConfig.from_mapping(mv))


def tracked(truth: pd.DataFrame, points: pd.DataFrame, tcfg: TrackerConfig, jobs: int
            ) -> tuple[pd.DataFrame, pd.DataFrame]:
    """(the tracker's tracks of the driving scenes of ``truth`` and ``points`` with tcfg's
    moving-object test in column ``moving``, the ego's poses): what the driving_track stage
    computes, for settings given as overrides."""
    pts, ego = tracker_input(truth, points)
    tracks = track_points(pts, tcfg, jobs=jobs)
    tracks["moving"] = moving_tracks(tracks, ego=ego, **moving_test_settings(tcfg.moving),
                                     points=points[["scene", "frame", "x_m", "y_m", "static"]])
    return tracks, ego


def criteria(tracks: pd.DataFrame, ego: pd.DataFrame, truth: pd.DataFrame, scenes,
             m: MovingConfig) -> None:
    """Print what each path of the moving test ``m`` read at the lead child's first confirmed
    row within 1 m of it in ``scenes`` (see the module docstring, ``--criteria``)."""
    s = moving_test_settings(m, grid=False)
    paths = {  # name: (its setting, value per row, passes); a path whose setting is null is off
        "speed": (m.speed_mps, lambda: np.hypot(tracks.vx_mps, tracks.vy_mps).to_numpy(),
                  lambda v: v > m.speed_mps),
        "chi2": (m.probability, lambda: velocity_chi2(tracks),
                 lambda v: v > chi2.ppf(m.probability, 2)),
        "approach_z": (m.approach_probability,
                       lambda: approach_z(tracks, ego, m.crossing_corridor_m),
                       lambda v: v > norm.ppf(m.approach_probability)),
        "doppler_first": (m.doppler_first_log_ratio,
                          lambda: doppler_motion_evidence(tracks, m.doppler_std_mps,
                                                          DOPPLER_FIRST_WINDOW),
                          lambda v: v >= m.doppler_first_log_ratio),
        "doppler_sum": (m.doppler_log_ratio_min,
                        lambda: doppler_evidence(tracks, ego, m.doppler_std_mps, m.doppler_llr,
                                                 m.doppler_log_ratio_floor,
                                                 spread_std_mps=m.doppler_spread_std_mps,
                                                 reference=m.doppler_reference),
                        lambda v: v > m.doppler_log_ratio_min),
        "crossing": (m.crossing_log_ratio,
                     lambda: crossing_evidence(tracks, ego, s["crossing_prior"])[0],
                     lambda v: v >= m.crossing_log_ratio)}
    checks = {k: (value(), ok) for k, (setting, value, ok) in paths.items()
              if setting is not None}
    t = tracks.assign(**{k: v for k, (v, _) in checks.items()})
    p = truth.loc[truth.pedestrian == "p0", ["scene", "frame", "x_m", "y_m", "vx_mps",
                                                "vy_mps"]].rename(
        columns={"scene": "group", "x_m": "px", "y_m": "py", "vx_mps": "true_vx",
                 "vy_mps": "true_vy"})
    j = t[t.confirmed & t.group.isin(scenes)].merge(p, on=["group", "frame"])
    j = j[np.hypot(j.x_m - j.px, j.y_m - j.py) <= 1.0]
    first = j.sort_values("frame").drop_duplicates("group").set_index("group")
    print(f"lead child's first confirmed row within 1 m: {len(first)} scenes, classed moving "
          f"there in {int(first.moving.sum())}; in each group, the share passing each path's "
          "threshold and the values read (median [p10, p90]):")
    late = first[~first.moving]
    for label, rows in (("moving there", first[first.moving]), ("not moving there", late)):
        print(f" {label} ({len(rows)}):")
        for k, (_, ok) in checks.items():
            v = rows[k].to_numpy(float)
            print(f"  {k:13s} passes {np.mean(ok(v)):.2f}; {np.median(v):.2f} "
                  f"[{np.percentile(v, 10):.2f}, {np.percentile(v, 90):.2f}]")
    print(" not moving there, filtered and true velocity:")
    for k in ("vx_mps", "vy_mps", "true_vx", "true_vy"):
        print(f"  {k:13s} {late[k].median():.2f} [{late[k].quantile(0.1):.2f}, "
              f"{late[k].quantile(0.9):.2f}] m/s")


def born_behind(tracks: pd.DataFrame, ego: pd.DataFrame, points: pd.DataFrame,
                eps_m: float) -> None:
    """Print the share of confirmed tracks per label born behind recent static points (see the
    module docstring, ``--born-behind``)."""
    birth = (tracks.sort_values("frame").drop_duplicates(["group", "track_id"])
             .merge(ego, on=["group", "frame"]))
    static = {g: d for g, d in points[points.static.to_numpy(bool)].groupby("scene")}
    behind = np.zeros(len(birth), bool)
    for i, r in enumerate(birth.itertuples()):
        d = static.get(r.group)
        if d is None:
            continue
        d = d[(d.frame < r.frame) & (d.frame >= r.frame - BEHIND_FRAMES)]
        rel_b = np.array([r.x_m - r.ego_x_m, r.y_m - r.ego_y_m])
        rng_b = np.hypot(*rel_b)
        rel = np.c_[d.x_m.to_numpy() - r.ego_x_m, d.y_m.to_numpy() - r.ego_y_m]
        rng = np.hypot(rel[:, 0], rel[:, 1])
        across = np.abs(rel[:, 0] * rel_b[1] - rel[:, 1] * rel_b[0]) / max(rng_b, 1e-9)
        ahead = rel @ rel_b > 0
        behind[i] = np.any(ahead & (rng <= rng_b - BEHIND_MARGIN_M) & (across <= BEHIND_WIDTH_M))
    lab = track_labels(tracks, points, eps_m).reindex(
        pd.MultiIndex.from_frame(birth[["group", "track_id"]])).to_numpy()
    for name, sel in (("lead child", lab == "p0"),
                      ("other pedestrians", pd.notna(lab) & (lab != "p0") & (lab != "static")),
                      ("static world", lab == "static")):
        print(f"confirmed tracks born behind static points, {name}: "
              f"{behind[sel].mean():.3f} of {int(sel.sum())}")


def main(argv: list[str]) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=REPO / "data")
    ap.add_argument("--half", default="tuning", choices=("tuning", "held_out", "all"))
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--criteria", action="store_true",
                    help="what the moving test read at the child's first confirmed row")
    ap.add_argument("--born-behind", action="store_true",
                    help="tracks born behind recent static points, per label")
    ap.add_argument("overrides", nargs="*")
    args = ap.parse_args(argv)
    tcfg = tracker_config(OmegaConf.load(REPO / "params.yaml"), args.overrides)
    truth = pd.read_parquet(args.data / "driving" / "truth.parquet")
    points = pd.read_parquet(args.data / "driving" / "points.parquet")
    mc = truth[truth.set == "monte_carlo"].scene.unique()
    half = replicate_half(mc)
    keep = mc if args.half == "all" else mc[half if args.half == "tuning" else ~half]
    truth, points = truth[truth.scene.isin(keep)], points[points.scene.isin(keep)]
    tracks, ego = tracked(truth, points, tcfg, args.jobs)
    lead = truth[truth.pedestrian == "p0"].groupby("scene").first()
    intr = lead.index[((lead.behaviour == "cross") & lead.collision.astype(bool)).to_numpy()]
    fp = (points[points.source == "p0"].merge(truth[["scene", "frame", "time_s"]]
                                              .drop_duplicates(), on=["scene", "frame"],
                                              suffixes=("_p", ""))
          .groupby("scene").time_s.min().reindex(intr).to_numpy(float))
    speed = (lead.ego_speed_mps.reindex(intr) * 3.6).round().to_numpy()
    first = first_track_times(tracks, truth, intr, steps=("born", "confirmed", "moving"))
    born, conf, mov = first["born"], first["confirmed"], first["moving"]
    print(f"{len(keep)} scenes ({args.half}), {len(intr)} intruding; overrides {args.overrides}")
    for name, t in (("born", born), ("confirmed", conf), ("moving", mov)):
        s = delay_stats(t - fp, speed)
        per = ", ".join(f"{k}: {v['median']}" for k, v in s["by_speed_kmh"].items())
        print(f"first point -> {name:9s}: median {s['median']} p90 {s['p90']} never "
              f"{s['n_never']}; by speed {per}")
    ttc = lead.collision_time_s.reindex(intr).to_numpy(float)
    print(f"TTC at first point median {np.nanmedian(ttc - fp):.2f} s, at first moving "
          f"{np.nanmedian(ttc - mov):.2f} s")
    labels = track_labels(tracks, points, tcfg.cluster_eps_m)
    per = tracks[tracks.confirmed].groupby(["group", "track_id"]).moving.any()
    lab = labels.reindex(per.index)
    clutter = per & (lab == "static").to_numpy()
    non = set(lead.index[(lead.behaviour != "cross").to_numpy()])
    g = clutter.index.get_level_values(0)
    print(f"static-world tracks classed moving: {int(clutter.sum())} of {int((lab == 'static').sum())}"
          f"; scenes with one: non-intruding {len(set(g[clutter.to_numpy()]) & non)} of "
          f"{len(non)}, intruding {len(set(g[clutter.to_numpy()]) - non)} of {len(intr)}")
    if args.criteria:
        criteria(tracks, ego, truth, intr, tcfg.moving)
    if args.born_behind:
        born_behind(tracks, ego, points, tcfg.cluster_eps_m)


if __name__ == "__main__":
    main(sys.argv[1:])
