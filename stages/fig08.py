"""fig08: the paper's Fig. 8, the hidden part of each car scene's path filled by every
interpolation method (errors on the hidden frames from reports/metrics/interpolate.json)."""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
import json

import pandas as pd

from blindspot.cli import main_stage
from blindspot.io import save_figure
from blindspot.report.path_figures import fig08_interpolation
from blindspot.stage import StageResult


def run(cfg, ctx):
    tracks = pd.read_parquet(ctx.dep("tracks.parquet"))
    truth = pd.read_parquet(ctx.dep("truth.parquet"))
    scenes = json.loads(ctx.dep("scenes.json").read_text())
    metrics = json.loads(ctx.dep("interpolate.json").read_text())
    fig = fig08_interpolation(tracks, truth, scenes, metrics)
    out = save_figure(fig, ctx.out("fig08.png"), dpi=110)
    print(f"fig08: {out} ({tracks.scene.nunique()} scenes x {tracks.method.nunique()} methods)")
    return StageResult(artifacts=[out])


if __name__ == "__main__":
    main_stage(run, "fig08")
