"""fig08: the paper's Fig. 8, the hidden part of each car scene's path filled by every
interpolation method (errors on the hidden frames from reports/metrics/interpolate.json)."""

import json

import pandas as pd

from blindspot import experiment
from blindspot.cli import main_stage
from blindspot.report.path_figures import fig08_interpolation


def run(cfg):
    tracks = pd.read_parquet(experiment.data_path(cfg, "interpolate", "tracks.parquet"))
    truth = pd.read_parquet(experiment.data_path(cfg, "simulate", "truth.parquet"))
    scenes = json.loads(experiment.data_path(cfg, "simulate", "scenes.json").read_text())
    metrics = json.loads(experiment.reports_path(cfg, "metrics", "interpolate.json").read_text())
    fig = fig08_interpolation(tracks, truth, scenes, metrics)
    out = experiment.save_report_figure(cfg, fig, "fig08", dpi=110)
    print(f"fig08: {out} ({tracks.scene.nunique()} scenes x {tracks.method.nunique()} methods)")


if __name__ == "__main__":
    main_stage(run, "fig08")
