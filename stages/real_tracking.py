"""real_tracking: the multi-target tracker on real point-cloud recordings (issue 12).

Each recording of cfg.real_tracking (conf/real_tracking/) is read (TI people-counting log with
TI's gtrack targets; RadHAR point cloud), its static points dropped, tracked with the tracker
group (with the recording's overrides) and scored: against TI's tracks with CLEAR MOT
(motmetrics) where a reference exists. Writes data/tracks/<name>.parquet (one row per live
track per frame, in the recording's own sensor frame), reports/metrics/real_tracking.json and
one figure per recording.
"""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)

from blindspot.cli import main_stage
from blindspot.config import shared_dir
from blindspot.io import save_figure, write_json, write_parquet
from blindspot.report.tracking_figures import fig_track_over_points, fig_tracks_against_reference
from blindspot.stage import StageResult
from blindspot.track.config import tracked_recordings
from blindspot.track.recordings import track_recording

# the keys of reports/metrics/real_tracking.json other checks read (issue 12), then the others
HEADLINE = ("n_tracks", "id_switches", "mota", "median_distance_m")


def run(cfg, ctx):
    metrics, figures = {}, []
    for name, (rec, tracker) in tracked_recordings(cfg).items():
        res = track_recording(rec, tracker, shared_dir(cfg))
        write_parquet(ctx.out(f"{name}.parquet"), res.tracks)
        metrics[name] = {k: res.metrics[k] for k in HEADLINE} | {
            k: v for k, v in res.metrics.items() if k not in HEADLINE}
        conf = res.tracks[res.tracks.confirmed]
        pts = res.points.dropna(subset=["x_m"])
        if rec.kind == "ti_gtrack":
            fig = fig_tracks_against_reference(
                pts, conf, res.reference, metrics=res.metrics,
                title=f"{name}: our tracks against TI's gtrack (sensor frame)")
        else:
            fig = fig_track_over_points(
                pts, conf, metrics=res.metrics, axes_labels=("x forward (m)", "y left (m)"),
                title=f"{name}: walker's track over the point cloud (ROS sensor frame)")
        figures.append(save_figure(fig, ctx.out(f"tracks_{name}.png")))
        m = res.metrics
        print(f"real_tracking {name}: {m['n_tracks']} confirmed tracks, ID switches "
              f"{m['id_switches']}, MOTA {m['mota']}, median distance {m['median_distance_m']} m,"
              f" longest track covers {100 * m['longest_track_coverage']:.1f} %")
    write_json(ctx.out("real_tracking.json"), metrics)
    flat = {f"{n}.{k}": v for n, d in metrics.items() for k, v in d.items()
            if isinstance(v, (int, float)) and not isinstance(v, bool)}
    return StageResult(metrics=flat, artifacts=figures)


if __name__ == "__main__":
    main_stage(run, "real_tracking")
