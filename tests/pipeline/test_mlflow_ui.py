"""The MLflow UI a person opens, loaded in headless Chromium (Debian's `chromium` package) from a
server this test starts on 127.0.0.1 and stops (issue 13).

The store holds two runs written by blindspot.runs (params, a metric, a figure). The checks
read the DOM Chromium renders: the experiment opens on its runs (not the GenAI overview); the
runs table lists both runs and orders them by the metric; a run's page shows the metric and its
value; the artifact page shows the figure as an image. And (issue 46) after a toy `dvc repro` and
`dvc exp run -S train.lr=0.01`, README's link opens the runs page with the parents' headline
metric column and the changed param in view. With ``BLINDSPOT_UI_SCREENSHOT=<png>`` the runs
pages are also saved there (reports/mlflow_runs_page.png is the last one's:
``-k headline_metric``).
"""

from __future__ import annotations

import contextlib
import os
import re
import shutil
import subprocess
import tempfile
from collections.abc import Iterator
from pathlib import Path

import pytest

from blindspot import runs
from tests.pipeline.scaleout import free_port, stop_group, wait_for_port
from tests.pipeline.toy_repo import VENV_BIN, clean_env

pytestmark = pytest.mark.slow  # a UI server and four page loads: ~1-2 min


def chromium() -> str:
    found = os.environ.get("BLINDSPOT_CHROMIUM") or shutil.which("chromium") or shutil.which(
        "chromium-browser")
    if not found:
        pytest.skip("headless Chromium not found (Debian: apt-get install chromium; or set "
                    "BLINDSPOT_CHROMIUM)")
    return found


def render(url: str, *, screenshot: Path | None = None) -> str:
    """The DOM of ``url`` after its scripts ran (20 s of virtual time), as Chromium renders it."""
    with tempfile.TemporaryDirectory(prefix="chromium-") as profile:
        args = [chromium(), "--headless", "--no-sandbox", "--disable-gpu",
                "--disable-dev-shm-usage", f"--user-data-dir={profile}",
                "--virtual-time-budget=20000", "--window-size=1600,1000"]
        if screenshot is not None:
            subprocess.run([*args, f"--screenshot={screenshot}", url], capture_output=True,
                           timeout=180, check=True)
        return subprocess.run([*args, "--dump-dom", url], capture_output=True, text=True,
                              timeout=180, check=True).stdout


def texts(dom: str) -> list[str]:
    return [t.strip() for t in re.findall(r">([^<>]+)</", dom) if t.strip()]


@pytest.fixture(scope="module")
def ui(tmp_path_factory: pytest.TempPathFactory) -> tuple[str, str, dict[str, str]]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    root = tmp_path_factory.mktemp("ui")
    run_ids = {}
    for hidden, ade in ((16, 0.31), (32, 0.27)):
        cfg = {"model": {"hidden_size": hidden}, "runs": {"enabled": True, "uri": None}}
        with runs.stage_run("evaluate", cfg, repo_root=root, run_name=f"evaluate-h{hidden}") as t:
            t.log_metrics({"lstm": {"ade_m": ade}})
            fig, ax = plt.subplots()
            ax.plot([0, 1, 2], [0, ade, 2 * ade])
            (root / f"h{hidden}").mkdir()
            fig.savefig(root / f"h{hidden}" / "fig08.png")
            plt.close(fig)
            t.log_artifact(root / f"h{hidden}" / "fig08.png", "figures")
            run_ids[f"evaluate-h{hidden}"] = t.run_id
    experiment_id = runs.get_client(runs.settings_from_cfg(cfg, root)).get_experiment_by_name(
        "blindspot").experiment_id
    with _mlflow_server(root) as base:
        yield base, experiment_id, run_ids


@contextlib.contextmanager
def _mlflow_server(root: Path) -> Iterator[str]:
    """An MLflow server on the repo's SQLite store, on a free loopback port: its base URL."""
    port = free_port()
    proc = subprocess.Popen(
        [str(VENV_BIN / "mlflow"), "server", "--backend-store-uri",
         f"sqlite:///{root / 'mlflow.db'}", "--host", "127.0.0.1", "--port", str(port),
         "--workers", "1"], env=clean_env(), stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        wait_for_port(port, proc, "mlflow server", timeout_s=180)
        yield f"http://127.0.0.1:{port}"
    finally:
        stop_group(proc)


def test_experiment_opens_on_its_runs(ui: tuple[str, str, dict[str, str]]) -> None:
    base, exp, run_ids = ui
    shot = os.environ.get("BLINDSPOT_UI_SCREENSHOT")
    dom = render(f"{base}/#/experiments/{exp}?workflowType=machine_learning",
                 screenshot=Path(shot) if shot else None)
    shown = texts(dom)
    assert "No data available" not in dom and "Run Name" in shown  # the runs table, no GenAI
    assert set(run_ids) <= set(shown)


def test_runs_table_orders_by_the_metric(ui: tuple[str, str, dict[str, str]]) -> None:
    base, exp, _ = ui
    for ascending, first in (("true", "evaluate-h32"), ("false", "evaluate-h16")):
        dom = render(f"{base}/#/experiments/{exp}/runs?workflowType=machine_learning"
                     f"&orderByKey=metrics.%60lstm.ade_m%60&orderByAsc={ascending}")
        names = [t for t in texts(dom) if t.startswith("evaluate-h")]
        assert names[0] == first, (ascending, names)


def test_run_page_shows_metric_and_figure(ui: tuple[str, str, dict[str, str]]) -> None:
    base, exp, run_ids = ui
    run = run_ids["evaluate-h32"]
    shown = texts(render(f"{base}/#/experiments/{exp}/runs/{run}"))
    i = shown.index("lstm.ade_m")
    assert shown[i + 1] == "0.27" and "model.hidden_size" in shown
    dom = render(f"{base}/#/experiments/{exp}/runs/{run}/artifacts/figures/fig08.png")
    assert re.search(r'<img[^>]*alt="figures/fig08.png"[^>]*src="blob:', dom), dom[-3000:]


# ------------------------------------------------ issue 46: what changed, in the first view


@pytest.fixture(scope="module")
def pipeline_ui(tmp_path_factory: pytest.TempPathFactory) -> tuple[str, str, str]:
    """A toy DVC repository after `dvc repro` and `dvc exp run -S train.lr=0.01`, its store
    served on 127.0.0.1; yields (base URL, experiment id, the experiment's name)."""
    from tests.pipeline.toy_repo import make_toy_repo, run

    root = make_toy_repo(tmp_path_factory.mktemp("ui-pipeline") / "repo")
    with open(root / "conf" / "runs" / "local.yaml", "a") as fh:  # below `headline:`
        fh.write("  toy: [score]\n")
    dvc = str(VENV_BIN / "dvc")
    for cmd in (["git", "init", "-q", "-b", "main"], ["git", "config", "user.email", "t@e.com"],
                ["git", "config", "user.name", "t"], [dvc, "init", "-q"],
                [dvc, "config", "hydra.enabled", "true"],
                [str(VENV_BIN / "python"), "-m", "blindspot", "params"], [dvc, "repro"],
                ["git", "add", "-A"], ["git", "commit", "-qm", "toy"]):
        run(cmd, root)
    proc = run([dvc, "exp", "run", "-S", "train.lr=0.01"], root)
    name = re.search(r"Ran experiment\(s\): (\S+)", proc.stdout + proc.stderr).group(1)
    experiment_id = runs.get_client(runs.settings_from_cfg(
        {"runs": {"enabled": True, "uri": None}}, root)).get_experiment_by_name(
        "blindspot").experiment_id
    with _mlflow_server(root) as base:
        yield base, experiment_id, name


def test_runs_page_opens_on_the_headline_metric_and_the_changed_param(
        pipeline_ui: tuple[str, str, str]) -> None:
    """README's link (blindspot.runs.view.runs_page_url): the runs table's first view shows the
    parent runs with their headline metric column and the overridden param, no clicking."""
    from blindspot.runs.view import runs_page_url

    base, exp, name = pipeline_ui
    shot = os.environ.get("BLINDSPOT_UI_SCREENSHOT")
    dom = render(runs_page_url(base, exp), screenshot=Path(shot) if shot else None)
    shown = texts(dom)
    assert "Run Name" in shown and f"exp {name}" in shown and "dvc repro" in shown, shown
    assert "toy.score" in shown, shown      # the headline metric's column ...
    assert "train.lr" in shown, shown       # ... and the param the experiment changed
    # their values: the experiment's lr and score (0.01 x 16 x 2 epochs), the baseline's score
    assert {"0.01", "0.32", "3.2"} <= set(shown), shown
