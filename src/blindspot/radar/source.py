"""The frame source interface: the simulator and recordings on disk are two implementations.

A frame is one complex64 cube ``(chirps, tx, rx, samples)`` (tx in firing order, rx in file
order). Frames are produced one at a time, so a long scene or capture never has to sit in memory.

Implementations: :class:`blindspot.radar.simulator.SimulatedSource`, the recordings on disk of
:mod:`blindspot.radar.capture` (built on :class:`RecordingFrames`, one per format) and
:class:`ArrayRecording` (frames already in memory).
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any, Protocol, runtime_checkable

import numpy as np

from blindspot.radar.array import VirtualArray, array_for
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


def check_frame_index(index: int, n: int) -> int:
    """Frame ``index`` of ``n`` as a non-negative int (negative counts from the end);
    ``IndexError`` outside."""
    i = int(index)
    if i < 0:
        i += n
    if not 0 <= i < n:
        raise IndexError(f"frame {index} outside a capture of {n} frames")
    return i


class RecordingFrames:
    """The frame-source methods shared by the recordings on disk.

    A subclass sets ``radar``, ``array`` and ``capture``: an opened capture with ``n_frames``
    and ``frame(i)`` -> complex64 (chirps, tx, rx, samples), read lazily; it adds ``times_s``.
    """

    radar: RadarConfig
    array: VirtualArray
    capture: Any

    @property
    def n_frames(self) -> int:
        return self.capture.n_frames

    def frame(self, index: int) -> np.ndarray:
        """complex64 (chirps, tx, rx, samples) of frame ``index`` (negative: from the end);
        ``IndexError`` outside."""
        return self.capture.frame(index)

    def __len__(self) -> int:
        return self.n_frames

    def __iter__(self) -> Iterator[np.ndarray]:
        for i in range(self.n_frames):
            yield self.capture.frame(i)


class ArrayRecording:
    """Frames already in memory, complex (frames, chirps, tx, rx, samples), as a frame source
    (times ``i * radar.frame_period_s``). The first frame's shape is checked against ``radar``
    (``ValueError`` naming ``origin``)."""

    def __init__(self, frames: np.ndarray, radar: RadarConfig, origin: str = "array"):
        self.radar = radar
        self.array = array_for(radar)
        self._frames = np.asarray(frames, dtype=np.complex64)
        for i in range(min(1, len(self._frames))):
            check_frame_shape(self._frames[i], radar, origin)

    @property
    def n_frames(self) -> int:
        return len(self._frames)

    @property
    def times_s(self) -> np.ndarray:
        """(n_frames,) frame start times, s."""
        return np.arange(self.n_frames) * self.radar.frame_period_s

    def frame(self, index: int) -> np.ndarray:
        """complex64 (chirps, tx, rx, samples) of frame ``index`` (negative: from the end)."""
        return self._frames[check_frame_index(index, self.n_frames)]

    def __len__(self) -> int:
        return self.n_frames

    def __iter__(self) -> Iterator[np.ndarray]:
        return iter(self._frames)
