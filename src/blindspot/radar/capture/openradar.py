"""OpenRadar example recordings (``.npy``): complex arrays of ADC codes.

The PreSense OpenRadar examples hold complex128 arrays whose real and imaginary parts are
*unsigned* 16-bit codes (0..65535) stored as floats; :func:`read_openradar_npy` reinterprets them
as two's-complement int16 (``v - 65536`` where ``v > 32767``). The file is small and holds no
frame structure of its own, so :class:`OpenRadarRecording` loads it whole and serves it as one
frame of ``(chirps, tx, rx, samples)``.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from blindspot.radar.capture.common import CaptureError, check_adc_bits
from blindspot.radar.config import RadarConfig
from blindspot.radar.source import ArrayRecording

__all__ = ["OpenRadarRecording", "read_openradar_npy"]


def read_openradar_npy(path: str | os.PathLike, *, n_tx: int | None = None,
                       unsigned: bool = True) -> np.ndarray:
    """Read an OpenRadar example ``.npy`` as complex64 int16 codes.

    unsigned : the file holds unsigned 16-bit codes in floats (the PreSense examples do); they
        are reinterpreted as two's-complement int16. With False the values must already be in
        the int16 range.
    n_tx : if given and the array is (chirps, n_tx * n_rx, samples), return the cube
        (1, chirps, n_tx, n_rx, samples) (virtual channels TX-major, as the examples store them).

    Returns the stored shape, e.g. (chirps, samples) or (chirps, channels, samples), unless
    ``n_tx`` reshapes it. Raises :class:`CaptureError` (file, what was found, what was expected)
    for a missing file, a real array, values that are not integer codes or lie outside the code
    range, or channels that do not split into ``n_tx`` TX, and for a file ``np.load`` cannot read
    as a plain array (cut, not .npy, pickled objects).
    """
    path = Path(path)
    if not path.is_file():
        raise CaptureError(path, "OpenRadar .npy file not found")
    try:  # memory-mapped: a header that claims more data than the file holds fails here
        a = np.load(path, allow_pickle=False, mmap_mode="r")
    except Exception as err:  # np.load's many ways to fail (ValueError, EOFError, SyntaxError..)
        raise CaptureError(path, "not a readable .npy file", f"{type(err).__name__}: {err}",
                           "a NumPy .npy array (no pickled objects)") from err
    a = np.array(a)
    if not np.iscomplexobj(a):
        raise CaptureError(path, "expected a complex array", str(a.dtype), "complex I + jQ")
    iq = np.stack([a.real, a.imag], axis=-1)
    if not np.all(np.isfinite(iq)) or not np.array_equal(iq, np.rint(iq)):
        raise CaptureError(path, "values are not integer ADC codes", "fractional or NaN values",
                           "integers")
    lo, hi = (0, 65535) if unsigned else (-32768, 32767)
    if iq.size and (iq.min() < lo or iq.max() > hi):
        raise CaptureError(path, "values outside the code range", f"[{iq.min():g}, {iq.max():g}]",
                           f"[{lo}, {hi}]" + (" (unsigned codes; pass unsigned=False for signed)"
                                              if unsigned else ""))
    codes = iq.astype(np.int64)
    if unsigned:
        codes = np.where(codes > 32767, codes - 65536, codes)
    z = (codes[..., 0] + 1j * codes[..., 1]).astype(np.complex64)
    if n_tx is None:
        return z
    if z.ndim != 3 or z.shape[1] % n_tx:
        raise CaptureError(path, f"cannot split channels into {n_tx} TX", str(z.shape),
                           f"(chirps, {n_tx} * n_rx, samples)")
    c, v, s = z.shape
    return z.reshape(1, c, n_tx, v // n_tx, s)


class OpenRadarRecording(ArrayRecording):
    """An OpenRadar ``.npy`` (chirps, n_tx * n_rx, samples) as a frame source of one frame
    (chirps, tx, rx, samples), channels split TX-major with ``radar.n_tx``.

    Of the profile, n_chirps, n_tx, n_rx and n_samples must match the stored shape
    (:class:`CaptureError` naming the key, the file's value and the profile's), adc_bits must be
    16 (the files hold 16-bit codes; else ``ConfigError``); tx_order and the array keys shape
    ``array``.
    """

    def __init__(self, path: str | os.PathLike, radar: RadarConfig, *, unsigned: bool = True):
        check_adc_bits(radar.adc_bits, (16,), "OpenRadar .npy")
        cube = read_openradar_npy(path, n_tx=radar.n_tx, unsigned=unsigned)
        _, c, t, r, s = cube.shape
        for key, value, want in (("n_chirps", c, radar.n_chirps),
                                 ("n_tx * radar.n_rx", t * r, radar.n_tx * radar.n_rx),
                                 ("n_samples", s, radar.n_samples)):
            if value != want:
                raise CaptureError(path, f"radar.{key} of profile '{radar.name}' does not match "
                                   f"the file (stored (chirps, n_tx * n_rx, samples) = "
                                   f"{(c, t * r, s)})", f"{value} in the file", f"{want}")
        super().__init__(cube, radar, str(path))
