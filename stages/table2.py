"""table2: the paper's Table 2 (radar parameters) beside the radar profile in cfg.radar, with the
values the paper does not state and the derived resolutions."""

from blindspot import experiment, tracking
from blindspot.cli import main_stage
from blindspot.io import write_text
from blindspot.report.tables import table2_radar


def run(cfg):
    out = write_text(experiment.reports_path(cfg, "tables", "table2.md"), table2_radar(experiment.radar(cfg)))
    tracking.current().log_artifact(out)
    print(f"table2: {out}")


if __name__ == "__main__":
    main_stage(run, "table2")
