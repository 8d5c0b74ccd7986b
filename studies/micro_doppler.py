"""The micro-Doppler spread that the moving test's spread ratio models
(``tracker.moving.doppler_spread_std_mps``, :func:`blindspot.safety.predict
.doppler_spread_log_ratio`), measured on the simulated driving scenes and on a real recording.
Prints figures, asserts nothing.

    BLINDSPOT_SHARED=../shared .venv/bin/python \
        studies/micro_doppler.py [--data data]

1. Simulated (DATA/driving/points.parquet of a ``dvc repro``; truth labels score only): the
   pooled within-object standard deviation of the points' ego-motion-compensated radial speed
   over the tracker's objects of two or more points that are all static-world or all one
   pedestrian's, per half of the Monte-Carlo replicates (``stages/driving_track.py
   doppler_spread_by_label``, the figures of driving_track.json ``doppler_spread``); then the
   lead pedestrian's objects in the intruding scenes and the static world's, by range band
   (the AEB gate admits requests at TTC 0.49-1.21 s: 1.4 m ahead at 10 km/h to 20 m at
   60 km/h).
2. Real: TI's people-counting log of four people walking indoors (``ti_gtrack_people`` of
   ``conf/real_tracking``; TI's chain, static clutter removed on the sensor, Doppler step
   0.080 m/s, radar at rest so the radial speed is the speed over ground), its points grouped
   into objects by the tracker configured for that recording: the same pooled spread, its
   per-object quantiles, and the share of objects that the configured spread ratio calls more
   likely a walker than static (llr > 0). No one here wrote that recording: it is the check
   that a real walker's points spread as widely as the simulated walker's.
3. Real: RadHAR's walker (``radhar_walk``, TI's out-of-box demo, Doppler steps of 0.6 m/s,
   static points at exactly 0): the objects of its moving points, and the share whose points
   all sit in one Doppler bin.

Time: about 7 s.

Conclusion: real walkers' points spread 0.14 m/s (TI people counting) and 0.08 m/s (RadHAR)
against the simulated 0.27 / 0.79-0.81 m/s: on TI's log the spread ratio would class 99.6 % of
walkers' objects static, so warning.moving_doppler_spread_std_mps is null (not used)
(conf/warning/default.yaml).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads
import numpy as np
import pandas as pd
from omegaconf import OmegaConf

REPO = Path(__file__).resolve().parents[1]

from blindspot.safety.config import WarningConfig  # noqa: E402
from blindspot.track.config import TrackerConfig, tracked_recordings  # noqa: E402
from blindspot.config import shared_dir  # noqa: E402
from blindspot.track.moving import doppler_spread_log_ratio  # noqa: E402
from blindspot.track.recordings import load_points  # noqa: E402


def main(argv: list[str]) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=REPO / "data")
    args = ap.parse_args(argv)
    from blindspot.synth.driving_tracks import (doppler_spread_by_label, monte_carlo_objects,
                               object_doppler_spreads, pooled_std)

    cfg = OmegaConf.load(REPO / "params.yaml")
    mv = TrackerConfig.from_cfg(cfg).moving
    pair = mv.doppler_spread_std_mps or (0.27, 0.79)
    print(f"spread ratio scored with static {pair[0]} m/s, walker {pair[1]} m/s"
          + (" (configured)" if mv.doppler_spread_std_mps
             else " (the measured pair; not configured)"))
    objects = monte_carlo_objects(pd.read_parquet(args.data / "driving/points.parquet"),
                                  TrackerConfig.from_cfg(cfg))
    for half, v in doppler_spread_by_label(objects).items():
        print(f"simulated, {half} half: " + "; ".join(
            f"{k} {x.get('pooled_std_mps', float('nan')):.3f} m/s ({x['n_objects']} objects, "
            f"{x['degrees_of_freedom']} dof)" for k, x in v.items()))

    per = objects[objects.n_sources == 1]
    lead = per[(per.source == "p0") & per.group.str.contains("_int_")]
    static = per[per.source == "static"]
    for lo, hi in ((0, 5), (5, 10), (10, 80)):
        band = [(name, q[(q.range_mean_m >= lo) & (q.range_mean_m < hi)])
                for name, q in (("lead pedestrian (intruding scenes)", lead),
                                ("static world", static))]
        print(f"simulated, objects {lo}-{hi} m away: " + "; ".join(
            f"{name} {pooled_std(q.n_points, q.doppler_spread_mps):.3f} m/s ({len(q)} objects)"
            if len(q) else f"{name}: none" for name, q in band))

    rec, tracker = tracked_recordings(cfg)["ti_gtrack_people"]
    pts, _ = load_points(rec, shared_dir(cfg))
    per = object_doppler_spreads(pts.dropna(subset=["x_m", "y_m"]), tracker, "velocity_mps")
    pooled = pooled_std(per.n_points, per.doppler_spread_mps)
    llr = doppler_spread_log_ratio(per, *pair)
    q = per.doppler_spread_mps.quantile([0.1, 0.5, 0.9]).to_numpy()
    print(f"real, TI people counting ({rec.path}): {len(per)} objects of >= 2 points "
          f"(median {per.n_points.median():.0f}), pooled spread {pooled:.3f} m/s, per-object "
          f"p10 / median / p90 {q[0]:.3f} / {q[1]:.3f} / {q[2]:.3f} m/s; spread ratio > 0 "
          f"(walker likelier) for {np.mean(llr > 0):.3f} of them, summed {llr.sum():.0f}")
    rec, tracker = tracked_recordings(cfg)["radhar_walk"]
    pts, _ = load_points(rec, shared_dir(cfg))
    moving = pts[~pts.static.astype(bool)].dropna(subset=["x_m", "y_m"])
    per = object_doppler_spreads(moving, tracker, "velocity_mps")
    print(f"real, RadHAR walk ({rec.path}): {len(per)} objects of >= 2 moving points (median "
          f"{per.n_points.median():.0f}), pooled spread "
          f"{pooled_std(per.n_points, per.doppler_spread_mps):.3f} m/s, all points in one Doppler "
          f"bin: {np.mean(per.doppler_spread_mps == 0):.3f} of them")


if __name__ == "__main__":
    main(sys.argv[1:])
