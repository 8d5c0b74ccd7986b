"""fig07: the paper's Fig. 7, the pedestrian's points in the three directions without the car
(a-c) and with it (d-f); with the car the frames where the pedestrian is hidden leave a gap."""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
import json

import pandas as pd

from blindspot.cli import main_stage
from blindspot.io import save_figure
from blindspot.radar.scene import car_twin, load_scenes
from blindspot.report.path_figures import fig07_scenes
from blindspot.stage import StageResult


def scene_pairs(cfg) -> list[tuple[str, str]]:
    """(no-car scene, car scene) per direction, in the order of conf/scene."""
    scenes = load_scenes(cfg.scene)
    pairs = [(twin, name) for name in scenes if (twin := car_twin(name, scenes))]
    if not pairs:
        raise ValueError(f"fig07: config key 'scene.scenes' has no '<walk>_car' / '<walk>_nocar' pair "
                         f"(found {list(scenes)})")
    return pairs


def run(cfg, ctx):
    points = pd.read_parquet(ctx.dep("points.parquet"))
    truth = pd.read_parquet(ctx.dep("truth.parquet"))
    scenes = json.loads(ctx.dep("scenes.json").read_text())
    pairs = scene_pairs(cfg)
    fig = fig07_scenes(points, truth, scenes, pairs)
    out = save_figure(fig, ctx.out("fig07.png"), dpi=110)
    print(f"fig07: {out} ({', '.join(f'{a} / {b}' for a, b in pairs)})")
    return StageResult(artifacts=[out])


if __name__ == "__main__":
    main_stage(run, "fig07")
