"""localise: one pedestrian point per frame (Cartesian, eq. 7), static clutter removed, the
frames where the pedestrian crossed the line of sight at zero Doppler bridged by track gating
(blindspot.dsp.zero_doppler), and the localisation error against the simulated truth (median
and 90th percentile per scene; blindspot.dsp.localisation). Beside them, as the baseline, the
paper's chain on the same detections: each detection at its range bin, the SNR-weighted centroid,
no bridge (``paper_chain`` in each scene's metrics)."""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
import pandas as pd

from blindspot.cli import main_stage
from blindspot.dsp.config import BridgeConfig, DetectConfig
from blindspot.dsp.localisation import localisation_errors
from blindspot.dsp.points import frame_points
from blindspot.dsp.zero_doppler import bridge_zero_doppler
from blindspot.io import write_json, write_parquet
from blindspot.radar.config import RadarConfig
from blindspot.stage import StageResult


def run(cfg, ctx):
    detect, bridge = DetectConfig.from_cfg(cfg), BridgeConfig.from_cfg(cfg)
    bin_m = RadarConfig.from_cfg(cfg).range_bin_m
    detections = pd.read_parquet(ctx.dep("detections.parquet"))
    truth = pd.read_parquet(ctx.dep("truth.parquet"))
    tables, paper = [], []
    for scene, det in detections.groupby("scene", sort=False):
        times = truth[truth.scene == scene].set_index("frame")["time_s"]
        on_grid = det.assign(range_m=det["range_bin"] * bin_m)
        paper.append(frame_points(on_grid, times, detect.min_speed_mps, detect.cluster_gap_m,
                                  estimator="centroid").assign(scene=scene))
        times = truth[truth.scene == scene].set_index("frame")["time_s"]
        pts = frame_points(det, times, detect.min_speed_mps, detect.cluster_gap_m,
                           estimator=detect.point_estimator)
        pts, bridged = bridge_zero_doppler(det, pts, times, detect.min_speed_mps, bridge,
                                           detect.point_estimator)
        tables.append(pts.assign(scene=scene, zero_doppler=bridged))
    points = pd.concat(tables, ignore_index=True)
    metrics = localisation_errors(points, truth)
    baseline = localisation_errors(pd.concat(paper, ignore_index=True), truth)
    for scene, m in metrics.items():  # points added by the zero-Doppler bridge; the baseline
        m["n_points_zero_doppler"] = int(points.zero_doppler[points.scene == scene].sum())
        m["paper_chain"] = {k: baseline[scene][k] for k in
                            ("error_median_m", "error_p90_m", "n_points")}
    write_parquet(ctx.out("points.parquet"), points)
    write_json(ctx.out("localise.json"), metrics)
    for scene, m in metrics.items():
        print(f"localise {scene}: {m['n_points']}/{m['n_frames']} frames with a point "
              f"({m['n_points_while_hidden']} while hidden, {m['n_points_zero_doppler']} at zero "
              f"Doppler), error median {m['error_median_m']:.3f} m, "
              f"p90 {m['error_p90_m']:.3f} m (paper's chain: {m['paper_chain']['n_points']} "
              f"points, {m['paper_chain']['error_median_m']:.3f} / "
              f"{m['paper_chain']['error_p90_m']:.3f} m)")
    return StageResult(metrics=metrics)


if __name__ == "__main__":
    main_stage(run, "localise")
