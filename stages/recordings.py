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

import numpy as np
from omegaconf import OmegaConf

from blindspot.cli import main_stage
from blindspot.config import shared_dir
from blindspot.dsp.chain import DetectionChain
from blindspot.dsp.config import CfarConfig, DetectConfig, DoaConfig
from blindspot.dsp.frame_io import write_frame_result
from blindspot.io import atomic_dir, save_figure, write_json, write_parquet
from blindspot.radar.array import array_for
from blindspot.radar.capture import open_recording
from blindspot.radar.config import RadarConfig
from blindspot.report.radar_figures import fig_recording
from blindspot.stage import StageResult


def run(cfg, ctx):
    summary, figures = {}, []
    # data/recordings is one directory out: filled under a temporary name and renamed when whole,
    # so a killed run leaves it absent or complete, never half-filled
    with atomic_dir(ctx.out("recordings")) as folder:
        for name, rec in cfg.recordings.items():
            det, first, summary[name] = process_recording(cfg, name, rec)
            write_parquet(folder / name / "detections.parquet", det)
            write_frame_result(folder / name / "frame0.npz", first, scene=name)
            fig = fig_recording(first.power, first.detections, first.range_axis_m,
                                first.velocity_axis_mps, f"{name} ({rec.kind}), frame 0")
            figures.append(save_figure(fig, ctx.out(f"recording_{name}.png")))
    write_json(ctx.out("recordings.json"), summary)
    return StageResult(metrics={n: {"detections_per_frame": s["detections_per_frame"]}
                                for n, s in summary.items()}, artifacts=figures)


def process_recording(cfg, name, rec):
    """One capture through the chain: (its detections, its first frame's result, its summary)."""
    path = Path(rec.path)
    if not path.is_absolute():
        path = shared_dir(cfg) / path
    where = f"recordings.{name}"
    radar = RadarConfig.from_mapping(rec.radar, where=f"{where}.radar")
    # reader options of the kind (e.g. strict: true to refuse a DCA1000 file with lost packets)
    options = OmegaConf.to_container(rec.get("options") or OmegaConf.create({}))
    try:
        source = open_recording(rec.kind, path, radar, **options)
    except ValueError as exc:
        if "has no option" not in str(exc):
            raise
        raise ValueError(f"config key '{where}.options': {exc}") from None
    # per-recording overrides of the chain's groups (e.g. a smaller array needs doa.subarray)
    chain = DetectionChain.from_config(radar, array_for(radar), *(
        kind.from_mapping(OmegaConf.merge(cfg[g], rec.get(g) or {}), where=f"{where}.{g}")
        for g, kind in (("cfar", CfarConfig), ("doa", DoaConfig), ("detect", DetectConfig))))
    det, _ = chain.process_many(source, progress=cfg.progress)
    first = chain.process(source.frame(0), frame=0)
    per_frame = det.groupby("frame").size().reindex(range(source.n_frames), fill_value=0)
    strongest = det.sort_values("power", ascending=False).drop_duplicates("frame")
    summary = {
        # where the data lay, relative to the shared folder: no output holds an absolute path
        "file": rec.path if not Path(rec.path).is_absolute() else path.name, "kind": rec.kind, "n_frames": int(source.n_frames),
        "detections_per_frame": float(per_frame.mean()),
        "strongest_range_m": [float(r) for r in strongest.sort_values("frame").range_m],
        "noise_floor_db": float(10 * np.log10(np.median(first.power))),
    }
    print(f"recordings {name}: {source.n_frames} frames, {per_frame.mean():.1f} detections/frame, "
          f"strongest return at {summary['strongest_range_m']} m")
    return det, first, summary


if __name__ == "__main__":
    main_stage(run, "recordings")
