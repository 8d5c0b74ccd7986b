"""recordings: each real recording from its capture to a decision (issues 12, 44).

Each entry of cfg.recordings (conf/recordings/) names a capture or a point-cloud log and how far
it goes (blindspot.safety.recording): points (static clutter flagged), tracks (tracker group),
predicted paths with their distributions (eval.kalman, warning.horizon_s ahead) and, from a car,
the warning / AEB request per frame: data/recordings/<name>/*.parquet (a raw capture's maps and
range-Doppler figure too; animation.gif with `animate: true`), reports/metrics/recordings.json.
"""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
from pathlib import Path

from blindspot.cli import main_stage
from blindspot.config import shared_dir
from blindspot.dsp.frame_io import write_frame_result
from blindspot.io import atomic_dir, save_figure, write_json, write_parquet
from blindspot.report.animation import recording_movie, render_movie
from blindspot.report.radar_figures import fig_recording
from blindspot.safety.config import WarningConfig
from blindspot.safety.recording import RAW_KINDS, RecordingEntry, run_recording
from blindspot.stage import StageResult, UndeclaredPath
from blindspot.track.config import TrackerConfig
from blindspot.traj.baselines import kalman_baseline
from blindspot.traj.config import EvalConfig


def run(cfg, ctx):
    ev, warning, summary, figures = EvalConfig.from_cfg(cfg), WarningConfig.from_cfg(cfg), {}, []
    with atomic_dir(ctx.out("recordings")) as folder:
        for name, rec in cfg.recordings.items():
            entry = RecordingEntry.from_mapping({**rec, "name": name}, where=f"recordings.{name}")
            path = Path(rec.path) if Path(rec.path).is_absolute() else shared_dir(cfg) / rec.path
            tracker = TrackerConfig.from_mapping({**cfg.tracker, **(rec.get("tracker") or {})},
                                                 where=f"recordings.{name}.tracker")
            res = run_recording(entry, rec, path, cfg, tracker, lambda dt: kalman_baseline(ev, dt),
                                warning, progress=cfg.progress)
            for key in ("points", "tracks", "predictions", "decisions", "detections", "reference"):
                if getattr(res, key) is not None:
                    write_parquet(folder / name / f"{key}.parquet", getattr(res, key))
            if entry.kind in RAW_KINDS:    # the figure: declared in dvc.yaml, else in its folder
                f = res.first
                write_frame_result(folder / name / "frame0.npz", f, scene=name)
                try:
                    target = ctx.out(f"recording_{name}.png")
                except UndeclaredPath:
                    target = folder / name / "range_doppler.png"
                figures.append(save_figure(fig_recording(
                    f.power, f.detections, f.range_axis_m, f.velocity_axis_mps,
                    f"{name} ({entry.kind}), frame 0"), target))
            if entry.animate:        # its animation (blindspot.report.animation)
                render_movie(recording_movie(name, res, every=entry.animate_every,
                                             max_frames=150), folder / name / "animation.gif")
            summary[name] = res.summary
    write_json(ctx.out("recordings.json"), summary)
    return StageResult(metrics={f"{n}.{k}": v for n, d in summary.items() for k, v in d.items()
                                if type(v) in (int, float)}, artifacts=figures)


if __name__ == "__main__":
    main_stage(run, "recordings")
