"""What every capture format shares: the error, int16 codes, size checks and atomic writes.

One place for the checks and messages the format modules (:mod:`.ti_cascade`, :mod:`.dca1000`,
:mod:`.openradar`) have in common, so that a truncated file or a bad frame index is reported the
same way whatever the format:

- :class:`CaptureError` names the file, the problem, the size (or value) found and expected;
- :func:`to_int16_iq` turns complex values into the (I, Q) int16 codes every writer stores;
- :func:`check_dims`, :func:`check_adc_bits`, :func:`check_range` are the profile and
  frame-range checks (one frame's index: :func:`blindspot.radar.source.check_frame_index`);
- :func:`iter_frames_of` walks a stacked cube or any iterable of frames (a frame source);
- :func:`atomic_files` writes several files through :func:`blindspot.io.atomic_path`, renaming
  them into place only when all are complete.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path
from typing import Any, Literal

import numpy as np

from blindspot.io import atomic_path
from blindspot.typed_config import ConfigError

__all__ = [
    "BYTES_PER_IQ",
    "CaptureError",
    "Int16Conversion",
    "atomic_files",
    "check_adc_bits",
    "check_dims",
    "check_range",
    "iter_frames_of",
    "to_int16_iq",
]

BYTES_PER_IQ = 4  # int16 I + int16 Q
Int16Conversion = Literal["exact", "round", "clip"]


class CaptureError(ValueError):
    """A capture file is missing, cut, or does not fit the chirp profile.

    Attributes ``path``, ``problem``, ``found``, ``expected``, ``note``; the message reads
    ``"{path}: {problem} (found {found}, expected {expected}); {note}"`` (the parts given).
    """

    def __init__(self, path: str | os.PathLike, problem: str, found: Any = None,
                 expected: Any = None, note: str | None = None):
        self.path, self.problem, self.found, self.expected = Path(path), problem, found, expected
        self.note = note
        msg = f"{path}: {problem}"
        if found is not None or expected is not None:
            msg += f" (found {found}, expected {expected})"
        if note:
            msg += f"; {note}"
        super().__init__(msg)


# ---------------------------------------------------------------------------------- int16 codes
def to_int16_iq(cube: np.ndarray, conversion: Int16Conversion = "exact",
                origin: str = "cube") -> np.ndarray:
    """Complex values (...) -> int16 array (..., 2) of (I, Q) codes.

    conversion: "exact" - values must already be integers within int16 (else CaptureError);
    "round" - round half to even, error if a rounded value falls outside int16;
    "clip" - round, then saturate at -32768 / 32767 like an ADC.
    NaN or infinite values always raise :class:`CaptureError` (naming ``origin``); an unknown
    ``conversion`` raises ``ValueError``.
    """
    if conversion not in ("exact", "round", "clip"):
        raise ValueError(f"conversion = {conversion!r}: expected 'exact', 'round' or 'clip'")
    z = np.asarray(cube)
    iq = np.stack([z.real, z.imag], axis=-1) if np.iscomplexobj(z) else np.stack(
        [z, np.zeros_like(z)], axis=-1)
    if iq.dtype.kind in "iu":
        ints = iq
    else:
        if not np.all(np.isfinite(iq)):
            raise CaptureError(origin, "values contain NaN or infinity, cannot write int16 codes")
        ints = np.rint(iq)
        if conversion == "exact" and not np.array_equal(ints, iq):
            bad = np.abs(ints - iq).max()
            raise CaptureError(origin, "values are not integer ADC codes (pass conversion="
                               "'round' or 'clip' to quantise)",
                               f"a fractional part up to {bad:.3g}", "integers")
    if conversion == "clip":
        return np.clip(ints, -32768, 32767).astype("<i2")
    lo, hi = ints.min(initial=0), ints.max(initial=0)
    if lo < -32768 or hi > 32767:
        raise CaptureError(origin, "values exceed the int16 range (pass conversion='clip' to "
                           "saturate)", f"[{lo:g}, {hi:g}]", "[-32768, 32767]")
    return ints.astype("<i2")


# ---------------------------------------------------------------------------------- checks
def check_dims(**dims: int) -> tuple[int, ...]:
    """The profile dimensions as ints, in the order given; ``ValueError`` naming the first that
    is not a positive integer (``n_samples = 0: expected a positive integer``)."""
    for key, v in dims.items():
        if int(v) < 1:
            raise ValueError(f"{key} = {v}: expected a positive integer")
    return tuple(int(v) for v in dims.values())


def check_adc_bits(adc_bits: int | None, supported: tuple[int, ...], fmt: str) -> int:
    """``adc_bits`` as an int if the format can honour it, else ``ConfigError('radar.adc_bits')``
    naming what ``fmt`` supports."""
    if adc_bits is None or int(adc_bits) not in supported:
        raise ConfigError("radar.adc_bits", adc_bits,
                          f"one of {list(supported)} ({fmt} files hold integer ADC codes in "
                          "16-bit words; null means unquantised simulator output, not a file)")
    return int(adc_bits)


def check_range(start: int, stop: int | None, n: int) -> tuple[int, int]:
    """Frames ``[start, stop)`` of ``n`` (``stop`` None: to the end); ``IndexError`` outside."""
    stop = n if stop is None else stop
    if not 0 <= start <= stop <= n:
        raise IndexError(f"frames [{start}, {stop}) outside [0, {n})")
    return int(start), int(stop)


def iter_frames_of(cube: np.ndarray | Iterable[np.ndarray],
                   frame_ndim: int) -> Iterator[np.ndarray]:
    """Frames of a stacked array (frames, ...) or of any iterable of frames (consumed once).

    A stacked array must have ``frame_ndim + 1`` axes, else ``ValueError``.
    """
    if isinstance(cube, np.ndarray):
        if cube.ndim != frame_ndim + 1:
            raise ValueError(f"cube has {cube.ndim} axes {cube.shape}; expected {frame_ndim + 1} "
                             "(frames, chirps, tx, rx, samples)")
        yield from cube
    else:
        yield from cube


# ---------------------------------------------------------------------------------- writing
@contextlib.contextmanager
def atomic_files(targets: Sequence[str | os.PathLike]) -> Iterator[list[Path]]:
    """Yield one temporary path per target (each from :func:`blindspot.io.atomic_path`); when
    the body succeeds, rename them into place in the order given; on any error remove them all
    and leave the targets as they were.

    The renames run last-entered first, so the temporaries are entered in reverse: a reader that
    trusts the last file of ``targets`` (e.g. an index) never sees it before the others.
    """
    with contextlib.ExitStack() as stack:
        temps = [stack.enter_context(atomic_path(t)) for t in reversed(targets)]
        yield temps[::-1]
