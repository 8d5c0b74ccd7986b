"""localise: one pedestrian point per frame (Cartesian, eq. 7), static clutter removed, and the
localisation error against the simulated truth (median and 90th percentile per scene)."""

import numpy as np
import pandas as pd

from blindspot import experiment, tracking
from blindspot.cli import main_stage
from blindspot.dsp.points import frame_points
from blindspot.io import write_json, write_parquet


def localisation_errors(points: pd.DataFrame, truth: pd.DataFrame) -> dict:
    """Per scene: frames with a point, frames seen while the torso was hidden, and the Euclidean
    error of the points against the true torso position (median, 90th percentile, mean)."""
    merged = points.merge(truth[["scene", "frame", "x_m", "y_m", "occluded"]],
                          on=["scene", "frame"], suffixes=("", "_true"))
    merged["error_m"] = np.hypot(merged.x_m - merged.x_m_true, merged.y_m - merged.y_m_true)
    out = {}
    for scene, frames in truth.groupby("scene", sort=False):
        m = merged[merged.scene == scene]
        e = m.error_m.to_numpy()
        out[scene] = {
            "n_frames": int(len(frames)),
            "n_points": int(len(m)),
            "n_hidden_frames": int(frames.occluded.sum()),
            "n_points_while_hidden": int(m.occluded.sum()),
            "error_median_m": float(np.median(e)) if len(e) else float("nan"),
            "error_p90_m": float(np.percentile(e, 90)) if len(e) else float("nan"),
            "error_mean_m": float(e.mean()) if len(e) else float("nan"),
        }
    return out


def run(cfg):
    detect = experiment.detect(cfg)
    detections = pd.read_parquet(experiment.data_path(cfg, "detect", "detections.parquet"))
    truth = pd.read_parquet(experiment.data_path(cfg, "simulate", "truth.parquet"))
    tables = []
    for scene, det in detections.groupby("scene", sort=False):
        times = truth[truth.scene == scene].set_index("frame")["time_s"]
        pts = frame_points(det, times, detect.min_speed_mps, detect.cluster_gap_m)
        tables.append(pts.assign(scene=scene))
    points = pd.concat(tables, ignore_index=True)
    metrics = localisation_errors(points, truth)
    write_parquet(experiment.data_path(cfg, "localise", "points.parquet"), points)
    write_json(experiment.reports_path(cfg, "metrics", "localise.json"), metrics)
    tracking.current().log_metrics(metrics)
    for scene, m in metrics.items():
        print(f"localise {scene}: {m['n_points']}/{m['n_frames']} frames with a point "
              f"({m['n_points_while_hidden']} while hidden), error median {m['error_median_m']:.3f} m, "
              f"p90 {m['error_p90_m']:.3f} m")


if __name__ == "__main__":
    main_stage(run, "localise")
