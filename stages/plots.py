"""plots: the DVC plots as SVG images, one line and legend entry per method or ensemble member
(blindspot.report.series_plots): the training history (validation RMSE per epoch, one line per
member) and the time-aligned error per prediction step (one line per method)."""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
import matplotlib
import pandas as pd

from blindspot.cli import main_stage
from blindspot.io import save_figure, write_text
from blindspot.report.series_plots import SVG_RC, error_by_step_wide, history_wide, series_figure
from blindspot.stage import StageResult


def run(cfg, ctx):
    history = history_wide(pd.read_csv(ctx.dep("history.csv")))
    error = error_by_step_wide(pd.read_csv(ctx.dep("error_by_step.csv")))
    outs = [write_text(ctx.out("train_history.csv"), history.to_csv(index=False)),
            write_text(ctx.out("error_by_step_wide.csv"), error.to_csv(index=False))]
    with matplotlib.rc_context(SVG_RC):
        outs.append(save_figure(series_figure(
            history, "epoch", xlabel="epoch", ylabel="validation one-step RMSE (m)",
            title="LSTM training: validation RMSE per epoch, one line per member"),
            ctx.out("train_history.svg")))
        outs.append(save_figure(series_figure(
            error, "time_s", xlabel="time ahead (s)", ylabel="time-aligned error (m)",
            title="Error per prediction step, one line per method", methods=True),
            ctx.out("error_by_step.svg")))
    print("plots: " + ", ".join(map(str, outs)))
    return StageResult(artifacts=outs)


if __name__ == "__main__":
    main_stage(run, "plots")
