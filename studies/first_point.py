"""Where the time goes between the lead pedestrian's first radar point and the first track the
decision assesses (issue 40), for tracker settings given as overrides. Prints figures, asserts
nothing.

    BLINDSPOT_SHARED=../shared PYTHONPATH=src .venv/bin/python studies/first_point.py \
        [--data data] [--half tuning|held_out|all] [tracker overrides key=value ...]

On the intruding Monte-Carlo scenes of one half (even replicates tune, odd are held out), per
scene: the time of the lead pedestrian's first radar point (truth label; scoring only), of the
first track row within 1 m of its true position, the first confirmed one, the first moving one
(the tracker's moving-object test, tracker.moving), each as a delay after the first point
(median, p90, per speed). On the non-intruding scenes of the same half, and on the intruding
ones, the confirmed tracks classed moving that are static-world clutter (no pedestrian point
within the cluster radius over their life: driving_track's labels): the price of seeing early.
Overrides: e.g. init_doppler_std_mps=0.3 doppler_confirm_log_ratio=4.6
moving.doppler_first_log_ratio=4.6. Time: a few minutes (the tracker on one half).
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

from blindspot.track.config import TrackerConfig
from blindspot.safety.evaluation import delay_stats, first_moving_s, replicate_half
from blindspot.synth.driving_tracks import track_labels, tracker_input
from blindspot.track.config import MovingConfig
from blindspot.track.moving import moving_test_settings, moving_tracks
from blindspot.track.tracker import track_points

REPO = Path(__file__).resolve().parents[1]


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


def main(argv: list[str]) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=REPO / "data")
    ap.add_argument("--half", default="tuning", choices=("tuning", "held_out", "all"))
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("overrides", nargs="*")
    args = ap.parse_args(argv)
    tcfg = tracker_config(OmegaConf.load(REPO / "params.yaml"), args.overrides)
    truth = pd.read_parquet(args.data / "driving" / "truth.parquet")
    points = pd.read_parquet(args.data / "driving" / "points.parquet")
    mc = truth[truth.set == "monte_carlo"].scene.unique()
    half = replicate_half(mc)
    keep = mc if args.half == "all" else mc[half if args.half == "tuning" else ~half]
    truth, points = truth[truth.scene.isin(keep)], points[points.scene.isin(keep)]
    tracks, _ = tracked(truth, points, tcfg, args.jobs)
    lead = truth[truth.pedestrian == "p0"].groupby("scene").first()
    intr = lead.index[((lead.behaviour == "cross") & lead.collision.astype(bool)).to_numpy()]
    fp = (points[points.source == "p0"].merge(truth[["scene", "frame", "time_s"]]
                                              .drop_duplicates(), on=["scene", "frame"],
                                              suffixes=("_p", ""))
          .groupby("scene").time_s.min().reindex(intr).to_numpy(float))
    speed = (lead.ego_speed_mps.reindex(intr) * 3.6).round().to_numpy()
    born = first_moving_s(tracks.assign(confirmed=True).drop(columns="moving"), truth, intr)
    conf = first_moving_s(tracks.drop(columns="moving"), truth, intr)
    mov = first_moving_s(tracks, truth, intr)
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


if __name__ == "__main__":
    main(sys.argv[1:])
