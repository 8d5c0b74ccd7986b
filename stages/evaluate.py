"""evaluate: the paper's error (Fig. 10) and time-aligned errors of every prediction method.

Per car scene and method: the paper's metric (each predicted point's distance to the nearest
point of the actual path, paper mean 0.09 m) against the simulated truth and against the radar
track of the same walk without the car (what the paper could measure); ADE/FDE at fixed
horizons; the error per prediction step (plot data for `dvc plots`). The scoring is
blindspot.traj.evaluation.
"""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
import pandas as pd

from blindspot.cli import main_stage
from blindspot.io import write_json, write_text
from blindspot.radar.scene import car_twin, load_scenes
from blindspot.report.paper_values import PATH_ERROR_MEAN_M
from blindspot.stage import StageResult
from blindspot.traj.evaluation import evaluate_predictions, mean_error_by_step


def run(cfg, ctx):
    predictions = pd.read_parquet(ctx.dep("predictions.parquet"))
    truth = pd.read_parquet(ctx.dep("truth.parquet"))
    points = pd.read_parquet(ctx.dep("points.parquet"))
    scenes = load_scenes(cfg.scene)
    dt = float(cfg.radar.frame_period_s)
    horizons = tuple(float(h) for h in cfg.eval.horizons_s)
    radar_tracks = {}  # the radar's points of the same walk without the car, from the start on
    for scene, pred in predictions.groupby("scene", sort=False):
        twin = car_twin(scene, scenes)
        if twin is not None:
            seen = points[(points.scene == twin) & (points.frame >= pred.frame.min())]
            radar_tracks[scene] = seen[["x_m", "y_m"]].to_numpy()
    metrics, curve = evaluate_predictions(predictions, truth, radar_tracks, dt, horizons)
    write_json(ctx.out("evaluate.json"), metrics)
    write_text(ctx.out("error_by_step.csv"), mean_error_by_step(curve, dt).to_csv(index=False))
    write_text(ctx.out("error_by_step_per_scene.csv"), curve.to_csv(index=False))
    for method, m in metrics.items():
        print(f"evaluate {method}: paper metric {m['path_error_mean_m']:.3f} m vs truth, "
              f"{m.get('path_error_radar_mean_m', float('nan')):.3f} m vs radar track "
              f"(paper {PATH_ERROR_MEAN_M.value} m); ADE {m['ade_m']:.3f} m, FDE {m['fde_m']:.3f} m")
    return StageResult(metrics={m: {k: v for k, v in d.items() if k != "per_scene"}
                                for m, d in metrics.items()})


if __name__ == "__main__":
    main_stage(run, "evaluate")
