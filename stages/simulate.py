"""simulate: the six paper scenes' truth (pedestrian path per frame, occlusion, car geometry).

Frames are not stored (detect and localise regenerate them from the same seeds); with
``simulate.write_captures: true`` each scene is also written as a TI MMWCAS cascade capture
under ``<paths.data_dir>/captures/<scene>``: an export for other tools, off by default and not a
DVC out (nothing in the pipeline reads it).
"""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
from pathlib import Path

import pandas as pd
from tqdm import tqdm

from blindspot.cli import main_stage
from blindspot.io import write_json, write_parquet
from blindspot.radar.config import RadarConfig, SimConfig
from blindspot.radar.scene import Scene, scene_truth
from blindspot.radar.scene import load_scenes
from blindspot.radar.simulator import SimulatedSource
from blindspot.stage import StageResult


def run(cfg, ctx):
    radar = RadarConfig.from_cfg(cfg)
    scenes = load_scenes(cfg.scene)
    truth = pd.concat(
        [scene_truth(sc, radar).assign(scene=name) for name, sc in scenes.items()],
        ignore_index=True,
    )
    geometry = {
        name: {
            "with_car": sc.with_car,
            "car_polygon_xy_m": (Scene(sc).car_polygon.tolist() if sc.with_car else None),
            "turn_deg": sc.pedestrian.turn_deg,
            "n_frames": sc.n_frames,
            "frame_period_s": radar.frame_period_s,
        }
        for name, sc in scenes.items()
    }
    write_parquet(ctx.out("truth.parquet"), truth)
    write_json(ctx.out("scenes.json"), geometry)
    hidden = truth.groupby("scene")["occluded"].mean()
    if cfg.simulate.write_captures:
        for name, sc in tqdm(scenes.items(), desc="captures", disable=not cfg.progress):
            SimulatedSource.from_config(sc, radar, SimConfig.from_cfg(cfg)).write_ti_cascade(
                Path(cfg.paths.data_dir, "captures", name))
    print(f"simulate: {len(scenes)} scenes, {len(truth)} frames; hidden fraction "
          + ", ".join(f"{k} {v:.2f}" for k, v in hidden.items()))
    return StageResult(metrics={**{f"hidden_fraction.{k}": float(v) for k, v in hidden.items()},
                                **{f"radar.{k}": v for k, v in radar.summary().items()}})


if __name__ == "__main__":
    main_stage(run, "simulate")
