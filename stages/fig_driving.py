"""fig_driving: the driving figures (issue 11): bird's-eye view of the figure scene (ego path,
parked cars, pedestrian truth, detections static / moving), the range-Doppler map of one frame
with the static world's Doppler curve and the unwrapped pedestrian, ego-speed error vs speed."""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
import json

import numpy as np
import pandas as pd

from blindspot.cli import main_stage
from blindspot.io import save_figure
from blindspot.report.driving_figures import (
    fig_driving_bev, fig_driving_range_doppler, fig_ego_speed_error,
)
from blindspot.stage import StageResult


def run(cfg, ctx):
    truth = pd.read_parquet(ctx.dep("truth.parquet"))
    scenes = json.loads(ctx.dep("scenes.json").read_text())
    det = pd.read_parquet(ctx.dep("driving_detections.parquet"))
    ego = pd.read_parquet(ctx.dep("driving_ego.parquet"))
    sweep = pd.read_parquet(ctx.dep("ego_speed_sweep.parquet"))
    with np.load(ctx.dep("driving_frame.npz")) as z:
        frame = {k: z[k] for k in z.files}
    name, keep = str(frame["scene"]), int(frame["frame"])
    if name not in scenes:
        raise ValueError(f"fig_driving: {ctx.dep('driving_frame.npz')} names scene {name!r}, not in "
                         f"{ctx.dep('scenes.json')}")
    tr = truth[truth.scene == name]
    info = scenes[name]
    title = (f"{name}: ego at {info['speed_kmh']:g} km/h past parked cars; "
             + ", ".join(f"{p['body']} {p['behaviour']}" for p in info["pedestrians"]))
    outs = [save_figure(fig_driving_bev(tr, det, info["car_polygons_xy_m"], title=title),
                        ctx.out("driving_bev.png"), dpi=110)]
    e = ego[ego.frame == keep].iloc[0]
    ped = tr[(tr.frame == keep) & (tr.pedestrian == info["pedestrians"][0]["name"])].iloc[0]
    outs.append(save_figure(fig_driving_range_doppler(
        frame, det[det.frame == keep], ego_speed_mps=float(e.ego_speed_mps),
        odometry_mps=float(e.odometry_mps), v_max_mps=float(frame["v_max_mps"]),
        pedestrian_truth={"angle_deg": ped.angle_deg, "radial_velocity_mps": ped.radial_velocity_mps,
                          "range_m": ped.range_m},
        title=f"{name}, frame {keep} (t = {ped.time_s:.1f} s): true ego speed "
              f"{e.true_speed_mps:.2f} m/s"), ctx.out("driving_range_doppler.png"), dpi=110))
    outs.append(save_figure(fig_ego_speed_error(sweep), ctx.out("driving_ego_speed.png"), dpi=110))
    print("fig_driving: " + ", ".join(map(str, outs)))
    return StageResult(artifacts=outs)


if __name__ == "__main__":
    main_stage(run, "fig_driving")
