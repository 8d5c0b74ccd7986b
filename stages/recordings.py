"""recordings: real radar recordings through the same detection chain (range-Doppler, CFAR, MUSIC).

Each entry of cfg.recordings (conf/recordings/) names a capture (kind: ti_cascade | dca1000 |
dca1000_packets | openradar_npy, path relative to paths.shared_dir or absolute), its radar profile
and optionally the reader's options (``options: {strict: true}``, ``{part: 1}``, ...). For each:
the detections of every frame, the maps of the first frame, and a range-Doppler figure with the
detections. Your own capture: add a conf/recordings/<name>.yaml, declare its figure
reports/figures/recording_<name>.png among the recordings stage's outs in dvc.yaml (and the
report stage's deps), and run `python -m blindspot recordings recordings=<name>`.
"""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
from pathlib import Path

from blindspot.cli import main_stage
from blindspot.config import shared_dir
from blindspot.dsp.frame_io import write_frame_result
from blindspot.dsp.recording import detect_recording
from blindspot.io import atomic_dir, save_figure, write_json, write_parquet
from blindspot.report.radar_figures import fig_recording
from blindspot.stage import StageResult


def run(cfg, ctx):
    summary, figures = {}, []
    # data/recordings is one directory out: filled under a temporary name and renamed when whole,
    # so a killed run leaves it absent or complete, never half-filled
    with atomic_dir(ctx.out("recordings")) as folder:
        for name, rec in cfg.recordings.items():
            path = Path(rec.path)
            if not path.is_absolute():
                path = shared_dir(cfg) / path
            det, first, summary[name] = detect_recording(name, rec, path, cfg,
                                                         progress=cfg.progress)
            write_parquet(folder / name / "detections.parquet", det)
            write_frame_result(folder / name / "frame0.npz", first, scene=name)
            fig = fig_recording(first.power, first.detections, first.range_axis_m,
                                first.velocity_axis_mps, f"{name} ({rec.kind}), frame 0")
            figures.append(save_figure(fig, ctx.out(f"recording_{name}.png")))
    write_json(ctx.out("recordings.json"), summary)
    return StageResult(metrics={n: {"detections_per_frame": s["detections_per_frame"]}
                                for n, s in summary.items()}, artifacts=figures)


if __name__ == "__main__":
    main_stage(run, "recordings")
