"""fig09: the paper's Fig. 9, the future path of each car scene predicted by every method from
the interpolated input track (the eval.prediction_input rows of data/interpolate/tracks.parquet)."""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
import json

import pandas as pd

from blindspot.cli import main_stage
from blindspot.io import save_figure
from blindspot.report.path_figures import fig09_prediction
from blindspot.stage import StageResult


def run(cfg, ctx):
    tracks_file = ctx.dep("tracks.parquet")
    tracks = pd.read_parquet(tracks_file)
    predictions = pd.read_parquet(ctx.dep("predictions.parquet"))
    truth = pd.read_parquet(ctx.dep("truth.parquet"))
    scenes = json.loads(ctx.dep("scenes.json").read_text())
    metrics = json.loads(ctx.dep("evaluate.json").read_text())
    method = str(cfg.eval.prediction_input)
    inputs = tracks[tracks.method == method]
    if inputs.empty:
        raise ValueError(f"fig09: config key 'eval.prediction_input' = {method!r} has no rows in "
                         f"{tracks_file} (methods there: {sorted(tracks.method.unique())})")
    fig = fig09_prediction(inputs, predictions, truth, scenes, metrics)
    out = save_figure(fig, ctx.out("fig09.png"), dpi=110)
    print(f"fig09: {out} ({predictions.scene.nunique()} scenes x {predictions.method.nunique()} methods)")
    return StageResult(artifacts=[out])


if __name__ == "__main__":
    main_stage(run, "fig09")
