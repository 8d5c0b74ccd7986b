"""The perception bounds' steps in the chain's order (the keys of safety_bound.json and
safety_held_out_bound.json, :data:`blindspot.safety.bound.BOUNDS`) with the words the README and
the report pages give each: what a perfect decision knows from the first frame of each piece of
information about the lead child. ``{m}``, ``{n}``: the M of N of the confirmation."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

__all__ = ["BOUND_STEPS", "bound_steps"]

BOUND_STEPS = (("line_of_sight", "its first frame in line of sight"),
               ("radar_point", "its first radar point"),
               ("confirmed_track", "a track confirmed on {m} of {n} frames of its points"))


def bound_steps(bound: Mapping[str, Any] | None) -> list[tuple[str, Mapping[str, Any]]]:
    """(words, the bound's block) of each step of :data:`BOUND_STEPS` that ``bound`` (a bounds
    file's content; None or {} for none) has with a finite ``avoided_after_visible_rate``, in
    the chain's order, the confirmation's M of N taken from its ``settings`` ("M", "N" where
    they are missing)."""
    if not isinstance(bound, Mapping):
        return []
    settings = bound.get("settings") or {}
    out = []
    for name, words in BOUND_STEPS:
        block = bound.get(name)
        rate = block.get("avoided_after_visible_rate") if isinstance(block, Mapping) else None
        if isinstance(rate, int | float) and not isinstance(rate, bool) and math.isfinite(rate):
            out.append((words.format(m=settings.get("confirm_m", "M"),
                                     n=settings.get("confirm_n", "N")), block))
    return out
