"""headline: reports/metrics/headline.json, the twenty numbers a table shows (blindspot.report.headline).

The pipeline's only DVC `metrics:` file, so `dvc exp show` and `dvc metrics diff` list these,
not the thousands of numbers of the detailed files (which stay outs that other stages and checks
read). A detailed file not yet written leaves its keys out."""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
import json

from blindspot.cli import main_stage
from blindspot.io import write_text
from blindspot.report.headline import SOURCES, headline_metrics, read_sources
from blindspot.stage import StageResult


def run(cfg, ctx):
    metrics = headline_metrics(read_sources({name: ctx.dep(f"{name}.json") for name in SOURCES}))
    # key order kept (write_json sorts): DVC's table shows the columns in the file's order
    out = write_text(ctx.out("headline.json"), json.dumps(metrics, indent=2) + "\n")
    print(f"headline: {out}, {len(metrics)} keys")
    return StageResult(metrics=metrics, artifacts=[out])


if __name__ == "__main__":
    main_stage(run, "headline")
