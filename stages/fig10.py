"""fig10: the paper's Fig. 10, Euclidean error against prediction step for every method: the
paper's metric (nearest actual point, against the truth and against the radar track of the walk
without the car) and the time-aligned error, with the paper's mean 0.09 m as reference."""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
import json

import pandas as pd

from blindspot.cli import main_stage
from blindspot.io import save_figure
from blindspot.report.error_figures import fig10_error
from blindspot.stage import StageResult


def run(cfg, ctx):
    curves = pd.read_csv(ctx.dep("error_by_step_per_scene.csv"))
    metrics = json.loads(ctx.dep("evaluate.json").read_text())
    fig = fig10_error(curves, metrics, dt_s=float(cfg.radar.frame_period_s))
    out = save_figure(fig, ctx.out("fig10.png"), dpi=110)
    print(f"fig10: {out} ({curves.method.nunique()} methods, {curves.step.max()} steps)")
    return StageResult(artifacts=[out])


if __name__ == "__main__":
    main_stage(run, "fig10")
