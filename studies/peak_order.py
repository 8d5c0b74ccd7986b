"""Which MUSIC peak is a detection's angle (issue 40, eighth pass): the driving scenes measured
twice by the fast measurement, once per ``doa.peak_order`` (``spectrum``: the highest
pseudo-spectrum peak, the paper's rule; ``power``: the most powerful by a joint least-squares
fit), with the same noise draws. For each: the lead pedestrian's points (truth label, scoring
only) against its true reference point, the share of its first ``--frames`` frames' points
more than ``--off`` m off across the road, and the static world's points that the static test
calls moving (ghosts: the point's angle puts it off the ego-motion Doppler curve). Prints
figures, asserts nothing.

    BLINDSPOT_SHARED=../shared .venv/bin/python studies/peak_order.py [--data data] \\
        [--set cpnco|monte_carlo] [--scenes 60] [--frames 5] [--off 0.5] [--jobs 2]

Reads data/driving/truth.parquet (the driving_scenes stage's) for the true positions; measures
the scenes anew (``--set cpnco``: Euro NCAP's 18 nominal CPNCO cells, about 1 min; ``--set
monte_carlo``: the main draw's first ``--scenes`` scenes, about 2 s of CPU per scene and order).

Conclusion (2026-12-06, docs/studies/first-point-to-brake.md, eighth pass), spectrum -> power:
static-world points off the Doppler curve (ghosts) 2,050 of 69,129 (2.97 %) -> 24 (0.03 %) on
the main draw's first 60 scenes, 833 of 25,200 (3.31 %) -> 19 (0.08 %) on CPNCO; the lead's
first-five-frame points more than 0.5 m across the road 5 of 377 -> 0 and 2 of 96 -> 0.
`doa.peak_order: power` was chosen on the tuning draw.
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads
import pandas as pd

from blindspot.config import compose
from blindspot.dsp.config import PEAK_ORDERS, CfarConfig, DetectConfig, DoaConfig, EgoMotionConfig
from blindspot.radar.config import RadarConfig, SimConfig
from blindspot.radar.driving import draw_scenarios
from blindspot.radar.scenario import load_scenarios
from blindspot.safety.ncap import nominal_scenes
from blindspot.synth.driving_measurement import measure_driving
from first_point_error import first_point_errors  # studies/ is on a script's path

REPO = Path(__file__).resolve().parents[1]


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=REPO / "data")
    ap.add_argument("--set", default="cpnco", choices=("cpnco", "monte_carlo"))
    ap.add_argument("--scenes", type=int, default=60, help="Monte-Carlo scenes (--set monte_carlo)")
    ap.add_argument("--frames", type=int, default=5)
    ap.add_argument("--off", type=float, default=0.5, help="m across the road")
    ap.add_argument("--jobs", type=int, default=2)
    args = ap.parse_args(argv)
    cfg = compose(config_dir=REPO / "conf")
    group, named = load_scenarios(cfg.scenario)
    if args.set == "cpnco":
        scenes = [s for s in nominal_scenes(named, group.monte_carlo.speeds_kmh)
                  if "_cpnco_" in s.name]
    else:
        scenes = draw_scenarios(group, named[group.figure_scene])[:args.scenes]
    truth = pd.read_parquet(args.data / "driving" / "truth.parquet")
    truth = truth[truth.scene.isin({s.name for s in scenes})]
    ego = EgoMotionConfig.from_cfg(cfg)
    print(f"peak_order: {len(scenes)} scenes ({args.set}); the lead's points in its first "
          f"{args.frames} frames; static points off the Doppler curve (|v| > "
          f"{ego.static_tolerance_mps} m/s over ground)")
    for order in PEAK_ORDERS:
        points = measure_driving(
            scenes, group, RadarConfig.from_cfg(cfg, "driving_radar"),
            CfarConfig.from_cfg(cfg, "driving_cfar"),
            replace(DoaConfig.from_cfg(cfg), peak_order=order), DetectConfig.from_cfg(cfg), ego,
            adc_headroom_db=SimConfig.from_cfg(cfg).adc_headroom_db, jobs=args.jobs).points
        e = first_point_errors(truth, points, args.frames)
        off = e.across_m > args.off
        static = points[points.source == "static"]
        print(f"  {order:8s} lead: {len(e)} points in {e.scene.nunique()} scenes, error median "
              f"{e.error_m.median():.2f} m, p90 {e.error_m.quantile(0.9):.2f} m; more than "
              f"{args.off} m across the road {off.sum()} ({off.mean():.1%}) in "
              f"{e[off].scene.nunique()} scenes | static world: {len(static)} points, "
              f"{(~static.static).sum()} ({(~static.static).mean():.2%}) off the curve",
              flush=True)


if __name__ == "__main__":
    main()
