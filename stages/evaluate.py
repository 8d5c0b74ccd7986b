"""evaluate: the paper's error (Fig. 10) and time-aligned errors of every prediction method.

Per car scene and method: the paper's metric (each predicted point's distance to the nearest
point of the actual path, paper mean 0.09 m) against the simulated truth and against the radar
track of the same walk without the car (what the paper could measure); ADE/FDE at fixed
horizons; the error per prediction step (plot data for `dvc plots`).
"""

import numpy as np
import pandas as pd

from blindspot import experiment, tracking
from blindspot.cli import main_stage
from blindspot.io import write_json, write_text
from blindspot.report.paper_values import PATH_ERROR_MEAN_M
from blindspot.traj.evaluation import score_prediction

ARRAYS = ("per_step_m", "path_error_m", "path_error_radar_m")


def run(cfg):
    predictions = pd.read_parquet(experiment.data_path(cfg, "predict", "predictions.parquet"))
    truth = pd.read_parquet(experiment.data_path(cfg, "simulate", "truth.parquet"))
    points = pd.read_parquet(experiment.data_path(cfg, "localise", "points.parquet"))
    scenes = experiment.scenes(cfg)
    dt = float(cfg.radar.frame_period_s)
    horizons = tuple(float(h) for h in cfg.eval.horizons_s)
    per_scene, curves = {}, []
    for (scene, method), pred in predictions.groupby(["scene", "method"], sort=False):
        pred = pred.sort_values("step")
        frames = pred.frame.to_numpy()
        tr = truth[truth.scene == scene].set_index("frame").loc[frames]
        twin = experiment.car_twin(scene, scenes)
        radar_track = None
        if twin is not None:
            seen = points[(points.scene == twin) & (points.frame >= frames[0])]
            radar_track = seen[["x_m", "y_m"]].to_numpy()
        s = score_prediction(pred[["x_m", "y_m"]].to_numpy(), tr[["x_m", "y_m"]].to_numpy(),
                             radar_track, dt, horizons)
        per_scene.setdefault(method, {})[scene] = {k: v for k, v in s.items() if k not in ARRAYS}
        curves.append(pd.DataFrame({
            "method": method, "scene": scene, "step": pred.step.to_numpy(),
            "time_s": pred.step.to_numpy() * dt, "error_m": s["per_step_m"],
            "path_error_m": s["path_error_m"],
            "path_error_radar_m": s.get("path_error_radar_m", np.full(len(pred), np.nan)),
        }))
    curve = pd.concat(curves, ignore_index=True)
    metrics = {}
    for method, scenes_m in per_scene.items():
        keys = next(iter(scenes_m.values())).keys()
        metrics[method] = {k: float(np.mean([m[k] for m in scenes_m.values()])) for k in keys}
        metrics[method]["per_scene"] = scenes_m
    write_json(experiment.reports_path(cfg, "metrics", "evaluate.json"), metrics)
    mean_curve = (curve.groupby(["method", "step"], sort=False)[["error_m", "path_error_m"]]
                  .mean().reset_index())
    mean_curve["time_s"] = mean_curve.step * dt
    write_text(experiment.reports_path(cfg, "plots", "error_by_step.csv"),
               mean_curve.to_csv(index=False))
    write_text(experiment.data_path(cfg, "evaluate", "error_by_step_per_scene.csv"),
               curve.to_csv(index=False))
    tracking.current().log_metrics({m: {k: v for k, v in d.items() if k != "per_scene"}
                                    for m, d in metrics.items()})
    for method, m in metrics.items():
        print(f"evaluate {method}: paper metric {m['path_error_mean_m']:.3f} m vs truth, "
              f"{m.get('path_error_radar_mean_m', float('nan')):.3f} m vs radar track "
              f"(paper {PATH_ERROR_MEAN_M.value} m); ADE {m['ade_m']:.3f} m, FDE {m['fde_m']:.3f} m")


if __name__ == "__main__":
    main_stage(run, "evaluate")
