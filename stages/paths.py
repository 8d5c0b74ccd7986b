"""paths: the paper's simulated training paths (section III), each point measured by the radar.

Clean walks (random start, speed, heading, gentle turns) are drawn by blindspot.traj.paths; every
point then goes through the radar chain (target -> range-Doppler -> CFAR -> MUSIC -> point, the
reduced-cube chain of blindspot.synth.path_measurement), so the data carry the radar's own errors.
"""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
import numpy as np

from blindspot.cli import main_stage
from blindspot.dsp.config import CfarConfig, DetectConfig, DoaConfig
from blindspot.io import write_parquet
from blindspot.radar.config import RadarConfig
from blindspot.radar.scene import load_scenes
from blindspot.stage import StageResult
from blindspot.synth.path_dataset import measure_path_set, path_table
from blindspot.synth.path_measurement import PedestrianModel
from blindspot.traj.config import DatasetConfig
from blindspot.traj.paths import random_path_set
from blindspot.typed_config import jobs


def run(cfg, ctx):
    radar = RadarConfig.from_cfg(cfg)
    dataset = DatasetConfig.from_cfg(cfg)
    paths = random_path_set(dataset.n_paths, dataset.path_spec(), seed=dataset.seed)
    walker = PedestrianModel.from_scene(next(iter(load_scenes(cfg.scene).values())))
    measured = measure_path_set(paths, radar, CfarConfig.from_cfg(cfg), DoaConfig.from_cfg(cfg),
                                DetectConfig.from_cfg(cfg), pedestrian=walker,
                                seed=dataset.seed, jobs=jobs(cfg),
                                progress=bool(cfg.progress))
    table = path_table(paths, measured, radar.frame_period_s)
    write_parquet(ctx.out("paths.parquet"), table)
    err = np.hypot(table.x_m - table.x_true_m, table.y_m - table.y_true_m).dropna()
    stats = {
        "n_paths": int(len(paths.xy)),
        "detection_rate": float(measured.detected.mean()),
        "point_error_median_m": float(err.median()),
        "point_error_p90_m": float(err.quantile(0.9)),
    }
    stats.update({f"detection_rate.{m}": float(g.x_m.notna().mean())
                  for m, g in table.groupby("motion")})
    print("paths: " + ", ".join(f"{k} {v:.3g}" for k, v in stats.items()))
    return StageResult(metrics=stats)


if __name__ == "__main__":
    main_stage(run, "paths")
