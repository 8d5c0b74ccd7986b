"""fig06: the paper's Fig. 6, one simulated frame through the detection chain (a range-velocity
map, b CA-CFAR detections, c MUSIC spectrum, d the pedestrian's point) and (e) the points of the
whole scene (eval.fig06_scene, frame eval.fig06_frame) accumulated over 100 frames."""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
import json

import numpy as np
import pandas as pd

from blindspot.cli import main_stage
from blindspot.dsp.frame_io import read_frame_result
from blindspot.dsp.points import to_cartesian
from blindspot.io import save_figure
from blindspot.report.radar_figures import fig06_detection
from blindspot.stage import StageResult


def run(cfg, ctx):
    frame = read_frame_result(ctx.dep("fig06_frame.npz"))
    detections = pd.read_parquet(ctx.dep("fig06_detections.parquet"))
    points = pd.read_parquet(ctx.dep("points.parquet"))
    truth = pd.read_parquet(ctx.dep("truth.parquet"))
    scenes = json.loads(ctx.dep("scenes.json").read_text())
    scene, frame_no = str(frame["scene"]), int(frame["frame"])
    if scene not in scenes:
        raise ValueError(f"fig06: {ctx.dep('fig06_frame.npz')} names scene {scene!r}, not in "
                         f"{ctx.dep('scenes.json')} ({sorted(scenes)})")
    tr = truth[truth.scene == scene].sort_values("frame")
    now = tr[tr.frame == frame_no].iloc[0]
    pt = points[(points.scene == scene) & (points.frame == frame_no)]
    static = detections[~detections.moving.to_numpy(bool) & detections.angle_deg.notna()]
    static_xy = np.column_stack(to_cartesian(static.range_m.to_numpy(), static.angle_deg.to_numpy()))
    fig = fig06_detection(
        frame, detections, true_angle_deg=float(now.angle_deg), true_xy_m=(now.x_m, now.y_m),
        point=None if pt.empty else pt.iloc[0][["x_m", "y_m", "range_m", "angle_deg"]].to_dict(), static_xy_m=static_xy,
        scene_points=points[points.scene == scene], scene_truth=tr,
        car_polygon=scenes[scene]["car_polygon_xy_m"], scene_name=scene)
    out = save_figure(fig, ctx.out("fig06.png"), dpi=110)
    print(f"fig06: {out} ({scene}, frame {frame_no}, {len(detections)} detections)")
    return StageResult(artifacts=[out])


if __name__ == "__main__":
    main_stage(run, "fig06")
