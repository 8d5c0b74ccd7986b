"""The DVC plots (issue 46): one line and legend entry per member / method, axes with units, and
`dvc plots show` HTML that needs no internet (SVG images, no vega from a CDN).

Fast: the wide tables, the legend entries and axis titles read back from the SVG text, the same
bytes twice, and the HTML `dvc plots show` writes for the real dvc.yaml's plots (no script, no
http). Slow (headless Chromium, network blocked): the page renders both images, with a
screenshot (``BLINDSPOT_PLOTS_SCREENSHOT=<png>`` keeps it).
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import matplotlib
import numpy as np
import pandas as pd
import pytest
import yaml

from blindspot.io import save_figure
from blindspot.report.series_plots import SVG_RC, error_by_step_wide, history_wide, series_figure

REPO = Path(__file__).resolve().parents[2]
DVC = Path(sys.executable).parent / "dvc"


def _history(n_members: int = 5, n_epochs: int = 15) -> pd.DataFrame:
    rows = [{"member": m, "seed": 10 + m, "epoch": e, "train_loss": 1.0, "train_rmse_m": 0.1,
             "val_rmse_m": 0.05 + 0.1 / (e + 1) + 0.002 * m, "val_rmse_euclid_m": 0.1}
            for m in range(n_members) for e in range(n_epochs)]
    return pd.DataFrame(rows)


def _error_curve() -> pd.DataFrame:
    committed = REPO / "reports" / "plots" / "error_by_step.csv"
    if committed.is_file():
        return pd.read_csv(committed)
    steps = np.arange(1, 26)
    return pd.concat([pd.DataFrame({"method": m, "step": steps, "time_s": steps * 0.1,
                                    "error_m": k * steps, "path_error_m": k * steps})
                      for m, k in (("lstm", 0.01), ("constant_velocity", 0.02), ("kalman", 0.015))])


def _write_plots(folder: Path) -> dict[str, int]:
    """The two plots as the plots stage draws them, into ``folder``; file name -> series."""
    history = history_wide(_history())
    error = error_by_step_wide(_error_curve())
    folder.mkdir(parents=True, exist_ok=True)
    with matplotlib.rc_context(SVG_RC):
        save_figure(series_figure(history, "epoch", xlabel="epoch",
                                  ylabel="validation one-step RMSE (m)", title="history"),
                    folder / "train_history.svg")
        save_figure(series_figure(error, "time_s", xlabel="time ahead (s)",
                                  ylabel="time-aligned error (m)", title="error", methods=True),
                    folder / "error_by_step.svg")
    return {"train_history.svg": history.shape[1] - 1,
            "error_by_step.svg": error.shape[1] - 2}


def legend_entries(svg: str) -> list[str]:
    """The texts of the legend group of a matplotlib SVG (its title first)."""
    start = svg.index('<g id="legend_1">')
    return re.findall(r"<text[^>]*>([^<]+)</text>", svg[start:])


def test_wide_tables_have_one_column_per_member_and_method() -> None:
    history = history_wide(_history())
    assert list(history.columns) == ["epoch", *[f"member {m} (seed {10 + m})" for m in range(5)]]
    assert len(history) == 15
    error = error_by_step_wide(_error_curve())
    assert list(error.columns[:2]) == ["step", "time_s"] and error.shape[1] - 2 == \
        _error_curve()["method"].nunique()
    assert error["step"].is_monotonic_increasing


def test_each_plot_has_one_legend_entry_per_series_and_titled_axes(tmp_path: Path) -> None:
    series = _write_plots(tmp_path)
    for name, n in series.items():
        svg = (tmp_path / name).read_text()
        entries = legend_entries(svg)
        assert entries[0] in {"series", "method"} and len(entries) - 1 == n, entries
        assert " (m)" in svg and ("epoch" in svg or "time ahead (s)" in svg)
    again = tmp_path / "again"
    _write_plots(again)
    assert all((again / n).read_bytes() == (tmp_path / n).read_bytes() for n in series)


def _dvc_plots_page(tmp_path: Path) -> tuple[Path, dict[str, int]]:
    """`dvc plots show` in a scratch repository holding the real dvc.yaml's plots section."""
    if not DVC.exists() or shutil.which("git") is None:
        pytest.skip(f"needs git and {DVC}")
    stages = yaml.safe_load((REPO / "dvc.yaml").read_text())["stages"]
    plots = [next(iter(p)) if isinstance(p, dict) else p
             for s in stages.values() for p in s.get("plots") or ()]
    assert sorted(Path(p).name for p in plots) == ["error_by_step.svg", "train_history.svg"]
    root = tmp_path / "repo"
    series = _write_plots(root / "reports" / "plots")
    (root / "dvc.yaml").write_text(yaml.safe_dump({"plots": plots}))
    env = {k: v for k, v in os.environ.items() if not k.startswith("DVC_")}
    env["DVC_NO_ANALYTICS"] = "1"
    for cmd in (["git", "init", "-q"], [str(DVC), "init", "-q"], [str(DVC), "plots", "show"]):
        subprocess.run(cmd, cwd=root, env=env, check=True, capture_output=True, timeout=120)
    return root / "dvc_plots" / "index.html", series


def test_dvc_plots_html_needs_no_internet(tmp_path: Path) -> None:
    page, series = _dvc_plots_page(tmp_path)
    html = page.read_text()
    assert "<script" not in html and "http" not in html.replace("http-equiv", "")
    images = re.findall(r'<img src="([^"]+)"', html)
    assert sorted(Path(i).name.split("_plots_")[-1] for i in images) == sorted(series)
    for image in images:
        svg = (page.parent / image).read_text()
        assert len(legend_entries(svg)) - 1 == series[Path(image).name.split("_plots_")[-1]]


@pytest.mark.slow
def test_dvc_plots_render_offline_in_chromium(tmp_path: Path) -> None:
    """Both plots drawn by headless Chromium with every host unresolvable (no internet)."""
    chromium = os.environ.get("BLINDSPOT_CHROMIUM") or shutil.which("chromium") or \
        shutil.which("chromium-browser")
    if not chromium:
        pytest.skip("headless Chromium not found (Debian: apt-get install chromium; or set "
                    "BLINDSPOT_CHROMIUM)")
    from PIL import Image

    page, series = _dvc_plots_page(tmp_path)
    shot = Path(os.environ.get("BLINDSPOT_PLOTS_SCREENSHOT") or tmp_path / "plots.png")
    with tempfile.TemporaryDirectory(prefix="chromium-") as profile:
        args = [chromium, "--headless", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                "--disable-background-networking", "--disable-component-update", "--disable-sync",
                "--no-first-run", f"--user-data-dir={profile}",
                "--host-resolver-rules=MAP * ~NOTFOUND", "--allow-file-access-from-files",
                "--virtual-time-budget=5000", "--window-size=1000,1800"]
        subprocess.run([*args, f"--screenshot={shot}", page.as_uri()], check=True,
                       capture_output=True, timeout=180)
        dom = subprocess.run([*args, "--dump-dom", page.as_uri()], check=True,
                             capture_output=True, text=True, timeout=180).stdout
    assert len(re.findall(r"<img ", dom)) == len(series)
    pixels = np.asarray(Image.open(shot).convert("L"))
    # two drawn plots, each with coloured lines and text: many non-white rows, one band per plot
    drawn_rows = (pixels < 200).sum(axis=1) > 5
    bands = np.flatnonzero(np.diff(drawn_rows.astype(int)) == 1).size
    assert drawn_rows.sum() > 400 and bands >= 2, (drawn_rows.sum(), bands)
