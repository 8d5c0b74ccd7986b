"""How early does the driving chain detect the crossing child? The perception bounds
(blindspot.safety.bound) of the Monte-Carlo scenes of chosen ego speeds, measured anew by the fast
driving measurement under variants of the detection settings. Prints figures, asserts nothing.

    BLINDSPOT_SHARED=../shared python studies/driving_detection.py \
        [--speeds 40] [--variants baseline,so_cfar,...] [--jobs 2] [--override OVERRIDE ...]

Per variant: radar points per frame, the lead child's points, and per speed the bound's avoided
rate and median true TTC of the request for "a radar point of the child" and "a 3-of-5
confirmable track" (the AEB requested at the first such frame on every intruding scene). The
scenes, truth and AEB model are the pipeline's (conf/, data/driving/truth.parquet and
scenes.json from `dvc repro driving_scenes`); only the detection settings change:

- ``baseline``: the configured driving chain (``driving_cfar``, ``detect``, ``ego_motion``;
  smallest-of CFAR since 2026-12-02: ``--override 'cfar@driving_cfar=paper'`` composes the
  config with the paper's CA-CFAR instead, the baseline of every figure measured before then;
  each ``--override`` is a Hydra override of the composed config, applied to every variant);
- ``ca_cfar`` / ``so_cfar`` / ``os_cfar`` / ``ca_pfa``: the ``cfar`` options paper / so / os /
  ca_pfa as the driving CFAR (the paper's cell-averaging, smallest-of, ordered-statistic,
  cell-averaging at a design Pfa);
- ``budget96``: 96 instead of ``ego_motion.max_detections`` angle estimates per frame;
- ``no_peak_only``: every CFAR cell, not only the 3 x 3 local maxima of the map;
- ``no_peak_budget400``: the same with 400 angle estimates per frame (the budget no longer
  binds: what the peak rule hides);
- ``rda_peaks``: ``ego_motion.peak_search: range_doppler_angle``, every CFAR cell beam-scanned
  with its neighbours and kept when it is a local maximum in range, Doppler and angle together
  (:func:`blindspot.dsp.detections.angle_peaks`); ``rda_peaks_budget96`` the same with 96 angle
  estimates per frame (whether the budget binds); ``rda_peaks_cand96`` / ``rda_peaks_cand512``
  with 96 / 512 instead of ``ego_motion.max_candidates`` (256) CFAR cells beam-scanned per
  frame, the strongest (what the scan costs against what it finds).

Time: about 20-40 s per variant and speed on 2 cores (``rda_peaks`` twice the baseline,
``no_peak_budget400`` about 5 min).

Conclusion: what hides the child from the cell-averaging CFAR chain is mostly the peak rule; at
40 km/h range-Doppler-angle peaks raise the radar-point bound 0.61 -> 0.78 and the confirmed-
track bound 0.33 -> 0.39 at 2.2x the time, the 48-estimate budget does not bind
(docs/studies/safety.md).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path

import pandas as pd
from omegaconf import OmegaConf

REPO = Path(__file__).resolve().parents[1]
VARIANTS = ("baseline", "ca_cfar", "so_cfar", "os_cfar", "ca_pfa", "budget96", "no_peak_only",
            "no_peak_budget400", "rda_peaks", "rda_peaks_budget96", "rda_peaks_cand96",
            "rda_peaks_cand512")


def settings(cfg, name: str, overrides: list[str] = ()) -> dict:
    """The detection settings of variant ``name`` (module docstring) on ``cfg``, the config
    composed with ``overrides`` (which the CFAR variants compose with as well)."""
    from blindspot.dsp.config import CfarConfig, DetectConfig, DoaConfig, EgoMotionConfig
    from blindspot.radar.config import RadarConfig, SimConfig
    from blindspot.radar.scenario import load_scenarios
    from blindspot.safety.config import WarningConfig
    from blindspot.track.config import TrackerConfig
    from blindspot.config import compose

    base = dict(cfar=CfarConfig.from_cfg(cfg, "driving_cfar"), detect=DetectConfig.from_cfg(cfg),
                ego=EgoMotionConfig.from_cfg(cfg))
    options = {"ca_cfar": "paper", "so_cfar": "so", "os_cfar": "os", "ca_pfa": "ca_pfa"}
    if name in options:
        return {**base, "cfar": CfarConfig.from_cfg(compose([*overrides,
                                                         f"cfar={options[name]}"]))}
    if name == "budget96":
        return {**base, "ego": dataclasses.replace(base["ego"], max_detections=96)}
    if name in ("no_peak_only", "no_peak_budget400"):
        out = {**base, "detect": dataclasses.replace(base["detect"], peak_only=False)}
        if name == "no_peak_budget400":
            out["ego"] = dataclasses.replace(base["ego"], max_detections=400)
        return out
    if name in ("rda_peaks", "rda_peaks_budget96", "rda_peaks_cand96", "rda_peaks_cand512"):
        ego = dataclasses.replace(base["ego"], peak_search="range_doppler_angle")
        if name == "rda_peaks_budget96":
            ego = dataclasses.replace(ego, max_detections=96)
        if name in ("rda_peaks_cand96", "rda_peaks_cand512"):
            ego = dataclasses.replace(ego, max_candidates=int(name.removeprefix("rda_peaks_cand")))
        return {**base, "ego": ego}
    return base


def main(argv: list[str]) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--speeds", default="40", help="comma-separated ego speeds, km/h")
    ap.add_argument("--variants", default="baseline,so_cfar,budget96,no_peak_only",
                    help=f"comma-separated, of {', '.join(VARIANTS)}")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--data", type=Path, default=REPO / "data")
    ap.add_argument("--override", action="append", default=[], metavar="OVERRIDE",
                    help="a Hydra override of the composed config (repeatable), e.g. "
                         "'cfar@driving_cfar=paper'")
    args = ap.parse_args(argv)
    names = args.variants.split(",")
    bad = sorted(set(names) - set(VARIANTS))
    if bad:
        ap.error(f"--variants: unknown {bad}; expected some of {list(VARIANTS)}")
    speeds = [float(s) for s in args.speeds.split(",")]

    from blindspot.dsp.config import CfarConfig, DetectConfig, DoaConfig, EgoMotionConfig
    from blindspot.radar.config import RadarConfig, SimConfig
    from blindspot.radar.scenario import load_scenarios
    from blindspot.safety.config import WarningConfig
    from blindspot.track.config import TrackerConfig
    from blindspot.config import compose
    from blindspot.radar.driving import draw_scenarios
    from blindspot.safety.assess import perception_bounds
    from blindspot.safety.outcome import body_boxes
    from blindspot.safety.risk import EgoShape
    from blindspot.synth.driving_measurement import measure_driving

    cfg = compose(args.override)
    drawn = OmegaConf.load(REPO / "params.yaml")
    for key in ("scenario", "driving_radar"):      # what data/driving/truth.parquet was drawn with
        if OmegaConf.to_container(cfg[key]) != OmegaConf.to_container(drawn[key]):
            ap.error(f"the composed config (conf/ with --override {args.override}) differs "
                     f"from params.yaml in `{key}`, but the scenes' truth under "
                     f"{args.data}/driving/ was drawn with params.yaml's; change the scenes "
                     "with `dvc exp run -S ...` instead")
    group, named = load_scenarios(cfg.scenario)
    radar = RadarConfig.from_cfg(cfg, "driving_radar")
    scenes = [s for s in draw_scenarios(group, named[group.figure_scene])
              if s.speed_kmh in speeds]
    if not scenes:
        ap.error(f"--speeds {args.speeds}: no Monte-Carlo scene at these speeds")
    truth = pd.read_parquet(args.data / "driving" / "truth.parquet")
    truth = truth[truth.scene.isin({s.name for s in scenes})]
    meta = json.loads((args.data / "driving" / "scenes.json").read_text())
    warning, tracker = WarningConfig.from_cfg(cfg), TrackerConfig.from_cfg(cfg)
    bodies = body_boxes(group)
    shape = EgoShape(group.ego.width_m, group.ego.length_m)
    print(f"driving_detection: {len(scenes)} Monte-Carlo scenes at {args.speeds} km/h"
          f"{''.join(f', {o}' for o in args.override)}; bound = AEB at the first frame of a "
          "radar point of the child / of a 3-of-5 confirmable track; avoided rate (median true "
          "TTC of the request, s)")
    for name in names:                               # a few variants
        s = settings(cfg, name, args.override)
        t0 = time.perf_counter()
        pts = measure_driving(scenes, group, radar, s["cfar"], DoaConfig.from_cfg(cfg), s["detect"],
                              s["ego"], adc_headroom_db=SimConfig.from_cfg(cfg).adc_headroom_db,
                              jobs=args.jobs, progress=False).points
        wall = time.perf_counter() - t0
        out = perception_bounds(truth, meta, pts, warning, bodies=bodies, shape=shape,
                                confirm=(tracker.confirm_m, tracker.confirm_n))
        per_frame = len(pts) / max(pts.groupby(["scene", "frame"]).ngroups, 1)

        def row(bound: str) -> str:
            return ", ".join(f"{k} km/h {v['avoided_rate']:.2f} ({v['lead_time_s_median']:.2f})"
                             for k, v in out[bound]["by_speed_kmh"].items())
        print(f"  {name:18s} {wall:5.0f} s  {per_frame:6.1f} points/frame, "
              f"{int((pts.source == 'p0').sum()):5d} of the child | radar point: "
              f"{row('radar_point')} | confirmed: {row('confirmed_track')}", flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
