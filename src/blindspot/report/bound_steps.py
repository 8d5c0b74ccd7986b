"""The perception bounds' steps in the chain's order (the keys of safety_bound.json and
safety_held_out_bound.json, :data:`blindspot.safety.bound.BOUNDS`) with the words the README and
the report pages give each: what a perfect decision knows from the first frame of each piece of
information about the lead child. ``{m}``, ``{n}``: the M of N of the confirmation."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

__all__ = ["BOUND_STEPS", "bound_steps", "same_draw"]

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


def same_draw(bound: Mapping[str, Any] | None, block: Mapping[str, Any] | None) -> bool:
    """Whether a bounds file's content (``bound``, its ``settings.seed``) and a draw's block of
    safety.json (``block``, its ``seed``) are of one draw: both seeds integers and equal. A
    bounds file of another draw, or one without its seed, must not stand beside the block's
    rows."""
    if not (isinstance(bound, Mapping) and isinstance(block, Mapping)):
        return False
    a, b = (bound.get("settings") or {}).get("seed"), block.get("seed")
    ints = all(isinstance(x, int) and not isinstance(x, bool) for x in (a, b))
    return ints and a == b
