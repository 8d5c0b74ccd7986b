"""The frame source interface: the simulator and recordings on disk are two implementations.

A frame is one complex64 cube ``(chirps, tx, rx, samples)`` (tx in firing order, rx in file
order). Frames are produced one at a time, so a long scene or capture never has to sit in memory.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Protocol, runtime_checkable

import numpy as np

from blindspot.radar.array import VirtualArray
from blindspot.radar.config import RadarConfig


@runtime_checkable
class FrameSource(Protocol):
    """Anything that yields radar frames of one chirp profile."""

    radar: RadarConfig
    array: VirtualArray

    @property
    def n_frames(self) -> int: ...

    @property
    def times_s(self) -> np.ndarray:
        """(n_frames,) start time of each frame, s."""
        ...

    def frame(self, index: int) -> np.ndarray:
        """complex64 (chirps, tx, rx, samples) of frame ``index``."""
        ...

    def __iter__(self) -> Iterator[np.ndarray]: ...


def iter_frames(source: FrameSource) -> Iterator[np.ndarray]:
    """Frames of any source in order (for sources that only implement ``frame``)."""
    for i in range(source.n_frames):
        yield source.frame(i)


def check_frame_shape(cube: np.ndarray, radar: RadarConfig, origin: str) -> None:
    """Raise a clear error when a cube does not match the radar profile."""
    expected = (radar.n_chirps, radar.n_tx, radar.n_rx, radar.n_samples)
    if cube.shape != expected:
        raise ValueError(
            f"{origin}: frame shape {cube.shape} does not match profile '{radar.name}' "
            f"(chirps, tx, rx, samples) = {expected}"
        )
