"""fig09: the paper's Fig. 9, the future path of each car scene predicted by every method from
the interpolated input track (the eval.prediction_input rows of data/interpolate/tracks.parquet)."""

import json

import pandas as pd

from blindspot import experiment
from blindspot.cli import main_stage
from blindspot.report.path_figures import fig09_prediction


def run(cfg):
    tracks = pd.read_parquet(experiment.data_path(cfg, "interpolate", "tracks.parquet"))
    predictions = pd.read_parquet(experiment.data_path(cfg, "predict", "predictions.parquet"))
    truth = pd.read_parquet(experiment.data_path(cfg, "simulate", "truth.parquet"))
    scenes = json.loads(experiment.data_path(cfg, "simulate", "scenes.json").read_text())
    metrics = json.loads(experiment.reports_path(cfg, "metrics", "evaluate.json").read_text())
    method = str(cfg.eval.prediction_input)
    inputs = tracks[tracks.method == method]
    if inputs.empty:
        raise ValueError(f"fig09: config key 'eval.prediction_input' = {method!r} has no rows in "
                         f"data/interpolate/tracks.parquet (methods there: {sorted(tracks.method.unique())})")
    fig = fig09_prediction(inputs, predictions, truth, scenes, metrics)
    out = experiment.save_report_figure(cfg, fig, "fig09", dpi=110)
    print(f"fig09: {out} ({predictions.scene.nunique()} scenes x {predictions.method.nunique()} methods)")


if __name__ == "__main__":
    main_stage(run, "fig09")
