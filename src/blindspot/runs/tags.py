"""The tags of a run: stage, working copy, git commit and dirtiness, DVC experiment, Hydra job, CPU kernels."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from blindspot import kernels

__all__ = ["run_tags"]


def _git(root: Path, *args: str) -> str | None:
    try:
        out = subprocess.run(
            ["git", *args], cwd=root, capture_output=True, text=True, timeout=10, check=True
        )
    except (OSError, subprocess.SubprocessError):
        return None
    return out.stdout.strip() or None


def run_tags(stage: str, work: Path, original: Path) -> dict[str, str]:
    tags = {"blindspot.stage": stage, "blindspot.workdir": str(work), "blindspot.repo": str(original)}
    exp_name = os.environ.get("DVC_EXP_NAME")
    baseline = os.environ.get("DVC_EXP_BASELINE_REV")
    if exp_name:
        tags["dvc.exp_name"] = exp_name
    if baseline:
        tags["dvc.baseline_rev"] = baseline
    if os.environ.get("DVC_STAGE"):
        tags["dvc.stage"] = os.environ["DVC_STAGE"]
    commit = baseline or _git(work, "rev-parse", "HEAD")
    if commit:
        tags["mlflow.source.git.commit"] = commit
        dirty = _git(work, "status", "--porcelain", "--untracked-files=no")
        tags["git.dirty"] = "true" if dirty else "false"
    tags["mlflow.source.name"] = f"stages/{stage}.py"
    tags["blindspot.kernels"] = kernels.STATE.summary()
    tags["mlflow.source.type"] = "LOCAL"
    if "hydra.core.hydra_config" not in sys.modules:  # no Hydra app in this process (DVC stage)
        return tags
    try:
        from hydra.core.hydra_config import HydraConfig

        if HydraConfig.initialized():
            hc = HydraConfig.get()
            if hc.mode is not None and hc.mode.name == "MULTIRUN":
                tags["hydra.job_num"] = str(hc.job.num)
            tags["hydra.overrides"] = " ".join(hc.overrides.task)
    except Exception:  # noqa: BLE001 - tags are best effort
        pass
    return tags
