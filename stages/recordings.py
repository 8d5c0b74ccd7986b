"""recordings: real radar recordings through the same detection chain (range-Doppler, CFAR, MUSIC).

Each entry of cfg.recordings (conf/recordings/) names a capture (kind: ti_cascade | dca1000 |
openradar_npy, path relative to paths.shared_dir or absolute) and its radar profile. For each:
the detections of every frame, the maps of the first frame, and a range-Doppler figure with the
detections. Your own capture: add a conf/recordings/<name>.yaml and run
`python -m blindspot recordings recordings=<name>`.
"""

from pathlib import Path

import numpy as np
from omegaconf import OmegaConf

from blindspot import experiment, tracking
from blindspot.cli import main_stage
from blindspot.config import shared_dir
from blindspot.dsp.chain import DetectionChain
from blindspot.io import atomic_open, write_json, write_parquet
from blindspot.radar.array import array_for
from blindspot.radar.capture import open_recording
from blindspot.radar.config import RadarConfig
from blindspot.report.radar_figures import fig_recording


def run(cfg):
    summary = {}
    tracker = tracking.current()
    for name, rec in cfg.recordings.items():
        path = Path(rec.path)
        if not path.is_absolute():
            path = shared_dir(cfg) / path
        radar = RadarConfig.from_mapping(rec.radar, where=f"recordings.{name}.radar")
        source = open_recording(rec.kind, path, radar)
        # per-recording overrides of the chain's groups (e.g. a smaller array needs doa.subarray)
        groups = {g: OmegaConf.merge(cfg[g], rec.get(g) or {}) for g in ("cfar", "doa", "detect")}
        chain = DetectionChain.from_config(radar, array_for(radar), **{
            f"cfg_{g}": c for g, c in groups.items()})
        det, _ = chain.process_many(source, progress=cfg.progress)
        first = chain.process(source.frame(0), frame=0)
        out = experiment.data_path(cfg, "recordings", name)
        write_parquet(out / "detections.parquet", det)
        with atomic_open(out / "frame0.npz", "wb") as f:
            np.savez_compressed(f, power=first.power, threshold=first.threshold, mask=first.mask,
                                range_axis_m=first.range_axis_m,
                                velocity_axis_mps=first.velocity_axis_mps)
        per_frame = det.groupby("frame").size().reindex(range(source.n_frames), fill_value=0)
        strongest = det.sort_values("power", ascending=False).drop_duplicates("frame")
        summary[name] = {
            "file": str(path), "kind": rec.kind, "n_frames": int(source.n_frames),
            "detections_per_frame": float(per_frame.mean()),
            "strongest_range_m": [float(r) for r in strongest.sort_values("frame").range_m],
            "noise_floor_db": float(10 * np.log10(np.median(first.power))),
        }
        fig = fig_recording(first.power, first.detections, first.range_axis_m,
                            first.velocity_axis_mps, f"{name} ({rec.kind}), frame 0")
        experiment.save_report_figure(cfg, fig, f"recording_{name}")
        print(f"recordings {name}: {source.n_frames} frames, {per_frame.mean():.1f} detections/frame, "
              f"strongest return at {summary[name]['strongest_range_m']} m")
    write_json(experiment.reports_path(cfg, "metrics", "recordings.json"), summary)
    tracker.log_metrics({n: {"detections_per_frame": s["detections_per_frame"]} for n, s in summary.items()})


if __name__ == "__main__":
    main_stage(run, "recordings")
