"""table2: the paper's Table 2 (radar parameters) beside the radar profile in cfg.radar, with the
values the paper does not state and the derived resolutions."""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
from blindspot.cli import main_stage
from blindspot.io import write_text
from blindspot.radar.config import RadarConfig
from blindspot.report.tables import table2_radar
from blindspot.stage import StageResult


def run(cfg, ctx):
    out = write_text(ctx.out("table2.md"), table2_radar(RadarConfig.from_cfg(cfg)))
    print(f"table2: {out}")
    return StageResult(artifacts=[out])


if __name__ == "__main__":
    main_stage(run, "table2")
