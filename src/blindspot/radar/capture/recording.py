"""Open a recording on disk by its kind: one frame source per capture format."""

from __future__ import annotations

import inspect
import os
from typing import Any

from blindspot.radar.capture.dca1000 import DCA1000Recording
from blindspot.radar.capture.dca1000_packets import DCA1000PacketRecording
from blindspot.radar.capture.openradar import OpenRadarRecording
from blindspot.radar.capture.ti_cascade import TICascadeRecording
from blindspot.radar.config import RadarConfig
from blindspot.radar.source import FrameSource

__all__ = ["RECORDING_KINDS", "open_recording"]

_RECORDINGS: dict[str, type] = {
    "ti_cascade": TICascadeRecording,
    "dca1000": DCA1000Recording,
    "dca1000_packets": DCA1000PacketRecording,
    "openradar_npy": OpenRadarRecording,
}
RECORDING_KINDS: tuple[str, ...] = tuple(_RECORDINGS)


def open_recording(kind: str, path: str | os.PathLike, radar: RadarConfig,
                   **options: Any) -> FrameSource:
    """A recording on disk as a frame source: ``kind`` in :data:`RECORDING_KINDS`.

    ``options`` go to the format's recording class as keywords (e.g. ``layout`` for
    ``dca1000`` and ``dca1000_packets``, ``strict=True`` for the DCA1000 kinds to raise
    :class:`~blindspot.radar.capture.common.CaptureError` where they would warn about the size,
    zero runs or lost packets, ``part`` for ``ti_cascade``). ``path`` is a file, the cascade's
    folder, or for ``dca1000_packets`` a list of the record's files in order. Raises
    ``ValueError`` for an unknown kind or an option the kind does not take (naming the options it
    takes); the format's errors otherwise.
    """
    if kind not in _RECORDINGS:
        raise ValueError(f"recording kind {kind!r} unknown: expected one of {RECORDING_KINDS}")
    cls = _RECORDINGS[kind]
    takes = _options_of(cls)
    if unknown := sorted(set(options) - set(takes)):
        raise ValueError(f"recording kind {kind!r} has no option(s) {unknown}: it takes {takes}")
    return cls(path, radar, **options)


def _keyword_only(fn: Any) -> tuple[list[str], bool]:
    """(keyword-only parameter names of ``fn``, whether it takes ``**kwargs`` too)."""
    params = inspect.signature(fn).parameters.values()
    return ([p.name for p in params if p.kind is inspect.Parameter.KEYWORD_ONLY],
            any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params))


def _options_of(cls: type) -> list[str]:
    """The options a recording class takes: its keyword-only parameters and, when it passes
    ``**options`` on to its capture class, that class's (but those the profile sets)."""
    names, passes_on = _keyword_only(cls)
    capture = getattr(cls, "_capture_class", None)
    if passes_on and capture is not None:
        inner, _ = _keyword_only(capture)
        names += [n for n in inner if n not in names and n != "adc_bits"]
    return names
