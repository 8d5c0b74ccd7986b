"""The import contracts of ``.importlinter`` (the one-way flow of ../shared/DESIGN.md) hold, and
every room of the library has its place in them."""

from __future__ import annotations

import configparser
import os
import pkgutil
import shutil
import subprocess
import sys
from pathlib import Path

import blindspot

REPO = Path(__file__).resolve().parents[1]
CONTRACTS = REPO / ".importlinter"
# top-level packages that are not rooms of the data flow: the benchmark command lines, and the
# MLflow glue of the stage runner (kept out of every room by the contract one-door-to-mlflow)
NOT_ROOMS = {"bench", "runs"}


def _lint(src: Path) -> subprocess.CompletedProcess:
    """`lint-imports` on the package found first on PYTHONPATH=src (no cache, no logo)."""
    env = {**os.environ, "PYTHONPATH": str(src)}
    code = ("import sys; from importlinter.cli import lint_imports; "
            f"sys.exit(lint_imports(config_filename={str(CONTRACTS)!r}, no_cache=True, "
            "no_logo=True))")
    return subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                          timeout=120)


def test_import_contracts_are_kept():
    res = _lint(Path(blindspot.__file__).parents[1])
    assert res.returncode == 0, f"broken import contracts (run `lint-imports`):\n{res.stdout}"


def test_every_room_is_in_the_flow_contract():
    parser = configparser.ConfigParser()
    parser.read(CONTRACTS)
    layers = parser["importlinter:contract:flow"]["layers"].split()
    rooms = {m.name for m in pkgutil.iter_modules(blindspot.__path__) if m.ispkg} - NOT_ROOMS
    missing = sorted(r for r in rooms if f"blindspot.{r}" not in layers)
    assert not missing, (f"{CONTRACTS.name}: the rooms {missing} have no place in the flow "
                         "contract; add each to its layer")


def test_a_wrong_import_breaks_the_contract(tmp_path):
    """The check is live: a copy of the package whose dsp imports traj fails it, naming dsp."""
    copy = tmp_path / "src" / "blindspot"
    shutil.copytree(Path(blindspot.__file__).parent, copy,
                    ignore=shutil.ignore_patterns("__pycache__"))
    (copy / "dsp" / "_wrong_way.py").write_text("from blindspot.traj import metrics  # noqa\n")
    res = _lint(copy.parent)
    assert res.returncode != 0
    assert "blindspot.dsp._wrong_way -> blindspot.traj.metrics" in res.stdout
