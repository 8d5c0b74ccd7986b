"""What a run changed, and which params a run logs.

- A stage's run logs the keys its ``dvc.yaml`` entry lists under ``params:`` (what it reads), not
  the whole composed config (hundreds of keys, which buried the runs table's metric columns); a
  stage that ``dvc.yaml`` does not know (a test's, a script's) logs everything. The whole config
  is still the run's artifact ``config/params.yaml``.
- A pipeline's parent run (``dvc repro``, ``dvc exp run -S ...``) logs its overrides: the keys
  whose values differ from what ``conf/`` composes to (for ``dvc exp run -S k=v`` exactly the
  ``-S`` values DVC composed into params.yaml), as params under their own names and as the tag
  ``blindspot.overrides`` (``k=v k2=v2``; empty for the defaults).
- A sweep's parent logs Hydra's override list the same way (``model.hidden_size`` ->
  ``32,64``); its name says the kind of sweep (``train-optuna-<study>``,
  ``train-submitit-<time>``, ``train-sweep-<time>`` on the basic or parallel launcher).
"""

from __future__ import annotations

import os
import time
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

from blindspot.config import flatten

__all__ = ["OVERRIDES_TAG", "stage_param_keys", "stage_params", "overrides_against_conf",
           "parse_overrides", "overrides_tag", "sweep_run_name"]

OVERRIDES_TAG = "blindspot.overrides"


def stage_param_keys(repo_root: str | os.PathLike[str], stage: str) -> tuple[str, ...] | None:
    """The dotted keys (or groups) ``dvc.yaml`` lists under ``params:`` for ``stage``; None when
    ``dvc.yaml`` has no such stage. A ``{file: [keys]}`` entry contributes its keys."""
    import yaml

    path = Path(repo_root) / "dvc.yaml"
    if not path.is_file():
        return None
    loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
    spec = ((yaml.load(path.read_text(), Loader=loader) or {}).get("stages") or {}).get(stage)
    if spec is None:
        return None
    keys: list[str] = []
    for item in spec.get("params") or ():
        if isinstance(item, Mapping):
            for listed in item.values():
                keys.extend(str(k) for k in (listed or ()))
        else:
            keys.append(str(item))
    return tuple(keys)


def stage_params(values: Mapping[str, Any], keys: Sequence[str] | None) -> dict[str, Any]:
    """``values`` flattened to dotted keys, only those equal to or under one of ``keys`` (all of
    them when ``keys`` is None)."""
    flat = flatten(values)
    if keys is None:
        return flat
    return {k: v for k, v in flat.items()
            if any(k == p or k.startswith(p + ".") for p in keys)}


def overrides_against_conf(values: Mapping[str, Any], conf_dir: str | os.PathLike[str]
                           ) -> dict[str, Any]:
    """Dotted key -> value of every key of ``values`` that differs from the composition of
    ``conf_dir`` (a key absent there counts; one absent from ``values`` is ``None``). Costs one
    Hydra composition (about a second)."""
    from blindspot.config import compose, params_diff

    diff = params_diff(values, compose(config_dir=conf_dir))
    return {d.key: (None if type(d.in_params).__name__ == "_Missing" else d.in_params)
            for d in diff}


def parse_overrides(overrides: Iterable[str]) -> dict[str, str]:
    """Hydra override strings (``model.hidden_size=32,64``, ``+search=lstm``, ``~key``) as key ->
    value text (the prefix ``+``/``++``/``~`` dropped; a deletion's value is empty)."""
    out: dict[str, str] = {}
    for text in overrides:
        key, _, value = str(text).partition("=")
        out[key.lstrip("+~")] = value
    return out


def overrides_tag(overrides: Mapping[str, Any]) -> str:
    """``k=v k2=v2`` (sorted by key), for the tag :data:`OVERRIDES_TAG`."""
    def show(v: Any) -> str:
        return "null" if v is None else str(v).lower() if isinstance(v, bool) else str(v)

    return " ".join(f"{k}={show(v)}" for k, v in sorted(overrides.items()))


def sweep_run_name(stage: str, sweeper_target: str | None, launcher_target: str | None,
                   study_name: str | None, now: float | None = None) -> str:
    """The name of a sweep's parent run: ``<stage>-optuna-<study>`` for an Optuna study (the
    study's name is what a second search with the same name continues), else
    ``<stage>-<kind>-<YYYYmmdd-HHMMSS>`` with kind ``submitit`` (submitit and SLURM), ``ray``,
    or ``sweep`` (the basic and joblib launchers)."""
    sweeper, launcher = (sweeper_target or "").lower(), (launcher_target or "").lower()
    if "optuna" in sweeper:
        return f"{stage}-optuna-{study_name or 'study'}"
    kind = "submitit" if "submitit" in launcher else "ray" if "ray" in launcher else "sweep"
    stamp = time.strftime("%Y%m%d-%H%M%S", time.localtime(time.time() if now is None else now))
    return f"{stage}-{kind}-{stamp}"
