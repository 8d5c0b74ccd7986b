"""report: reports/README.md, every figure and table of the pipeline with our numbers beside the
paper's and the command that regenerates each (blindspot.report.page), and README.md's results
block (blindspot.report.readme). Metrics files that do not exist yet (e.g. the ETH/UCY
benchmark's) are reported as not run; the page still builds."""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
import json
from pathlib import Path

from blindspot.cli import main_stage
from blindspot.io import write_text
from blindspot.report.page import FigureEntry, build_page
from blindspot.report.readme import METRICS_FILES, update_readme
from blindspot.stage import StageResult, UndeclaredPath

METRICS = ("localise", "train", "interpolate", "evaluate", "ethucy", "benchmark", "calibration",
           "train_direct")


def read_json(path: Path) -> dict | None:
    return json.loads(path.read_text()) if path.is_file() else None


def recording_figures(ctx) -> list[FigureEntry]:
    """The recordings stage's figures that exist, in the order of reports/metrics/recordings.json."""
    recordings = read_json(ctx.dep("recordings.json")) or {}
    page_dir = ctx.out("reports/README.md").parent
    out = []
    for name, info in recordings.items():
        try:
            figure = ctx.dep(f"recording_{name}.png")
        except UndeclaredPath:
            continue
        rel = figure.relative_to(page_dir).as_posix()
        if figure.is_file():
            out.append(FigureEntry(
                "recordings", rel, f"Real recording: {name}",
                f"Range-Doppler map of frame 0 of `{Path(info.get('file', name)).name}` ({info.get('kind')}) "
                f"with its CFAR detections; {info.get('detections_per_frame', float('nan')):.1f} "
                "detections per frame."))
    return out


def run(cfg, ctx):
    metrics = {name: read_json(ctx.dep(f"{name}.json")) for name in METRICS}
    tables = {}
    for name in ("table1", "table2", "benchmark"):
        path = ctx.dep(f"{name}.md")
        tables[name] = path.read_text() if path.is_file() else None
    page = build_page(metrics, tables, extra_figures=recording_figures(ctx))
    out = write_text(ctx.out("reports/README.md"), page)
    # README.md's results block: every number of it from the metrics (tests/report/test_readme.py)
    update_readme(ctx.out("README.md"), {n: read_json(ctx.dep(f"{n}.json")) for n in METRICS_FILES})
    missing = [n for n, m in metrics.items() if m is None]
    print(f"report: {out}" + (f" (not yet run: {', '.join(missing)})" if missing else ""))
    return StageResult(artifacts=[out])


if __name__ == "__main__":
    main_stage(run, "report")
