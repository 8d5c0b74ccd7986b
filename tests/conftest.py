"""Shared test fixtures: repository and shared-data locations."""

import os
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("BLINDSPOT_SHARED", REPO_ROOT.parent / "shared")).resolve()


@pytest.fixture(scope="session")
def shared_dir() -> Path:
    if not (SHARED / "data").is_dir():
        pytest.skip(f"shared data folder not found at {SHARED} (set BLINDSPOT_SHARED)")
    return SHARED


@pytest.fixture(scope="session")
def composed_config():
    """The real conf/ composed with the tiny run-size profile (``profile=tiny``), resolved:
    what the stages see in the pipeline test. Treat it as read-only."""
    from blindspot.config import compose

    return compose(["profile=tiny"], config_dir=REPO_ROOT / "conf")


# `make test` runs the files on one worker per core, each file whole on one worker, in collection
# order (xdist --dist loadfile --no-loadscope-reorder). The tiny `dvc repro` and the experiment
# after it take most of one worker's time: started first, the other worker runs the rest of the
# suite beside them; started last (xdist's default order: most tests first), the run waited for it.
LONGEST_FIRST = ("tests/pipeline/test_repro.py",)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    rank = {path: i for i, path in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.nodeid.split("::", 1)[0], len(rank)))


# Property-based tests (hypothesis): derandomised so CI and a developer see the same examples;
# no per-example deadline (a cold import or a first FFT plan can take a second on a busy machine).
# `HYPOTHESIS_PROFILE=thorough pytest ...` draws many more examples on purpose.
from hypothesis import HealthCheck, settings  # noqa: E402

settings.register_profile("ci", derandomize=True, deadline=None, max_examples=60,
                          suppress_health_check=[HealthCheck.too_slow], database=None)
settings.register_profile("thorough", deadline=None, max_examples=2000,
                          suppress_health_check=[HealthCheck.too_slow])
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))
