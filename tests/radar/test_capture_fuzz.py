"""Fuzzing the capture readers (issue 9): random truncation, random bytes, random padding and
random profiles for the DCA1000 headerless and packet-level readers, the TI cascade (data and
``_idx.bin``) and OpenRadar ``.npy`` files.

Whatever the input, a reader either returns a cube of the shape the profile implies or raises one
of the project's documented errors (:class:`CaptureError`, :class:`ConfigError`, the ``ValueError``
the docstrings name for a profile a layout cannot carry), and warns only with its own
``UserWarning`` naming the file: never a bare numpy / struct / pickle exception, never a silently
wrong shape. Inputs are a few kB, so each property runs in about a second.
"""

from __future__ import annotations

import os
import re
import tempfile
import warnings
from contextlib import contextmanager
from functools import lru_cache
from pathlib import Path

import numpy as np
from hypothesis import event, given
from hypothesis import strategies as st

from blindspot.radar.capture import (
    CaptureError,
    DCA1000PacketCapture,
    read_dca1000,
    read_dca1000_packets,
    read_openradar_npy,
    read_ti_cascade,
    write_dca1000,
    write_dca1000_packets,
    write_ti_cascade,
)
from blindspot.typed_config import ConfigError

# plain ValueErrors the readers' docstrings name: a profile the DCA1000 layout cannot carry, a
# bad skip_bytes or payload size
DOCUMENTED_VALUE_ERRORS = re.compile(r"^(n_samples = \d+: the xwr16xx|n_rx = \d+: the xwr14xx|"
                                     r"skip_bytes = |payload_bytes = )")


def scratch() -> tempfile.TemporaryDirectory:
    """A temporary folder, in memory where the machine has /dev/shm (hundreds of small files
    are written and fsync'ed per property)."""
    shm = Path("/dev/shm")
    return tempfile.TemporaryDirectory(dir=shm if shm.is_dir() and os.access(shm, os.W_OK)
                                       else None)


@contextmanager
def only_documented_outcomes(folder: str):
    """Run the body; let only documented errors out (swallowed), and only our warnings."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            yield
            event("read")
        except (CaptureError, ConfigError) as err:
            event(type(err).__name__)
        except ValueError as err:
            assert DOCUMENTED_VALUE_ERRORS.match(str(err)), f"undocumented ValueError: {err!r}"
            event("ValueError")
    for w in caught:
        assert w.category is UserWarning and str(w.message).startswith(folder), \
            f"unexpected warning {w.category.__name__}: {w.message}"


def check_cube(cube: np.ndarray, n_chirps: int, n_tx: int, n_rx: int, n_samples: int) -> None:
    assert cube.dtype == np.complex64 and cube.ndim == 5 and cube.shape[0] >= 1
    assert cube.shape[1:] == (n_chirps, n_tx, n_rx, n_samples)


def codes(rng: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
    iq = rng.integers(-32768, 32768, size=shape + (2,))
    return (iq[..., 0] + 1j * iq[..., 1]).astype(np.complex64)


def mutate(data: bytes, draw) -> bytes:
    """``data`` cut, padded (zeros or random) at either end, or with bytes overwritten."""
    kind = draw(st.sampled_from(["keep", "keep", "cut", "pad_end", "pad_start", "flip",
                                 "random"]))
    if kind == "cut":
        return data[:draw(st.integers(0, len(data)))]
    if kind in ("pad_end", "pad_start"):
        pad = draw(st.one_of(st.binary(max_size=300),
                             st.integers(0, 300).map(lambda n: bytes(n))))
        return data + pad if kind == "pad_end" else pad + data
    if kind == "flip" and data:
        b = bytearray(data)
        for _ in range(draw(st.integers(1, 8))):
            b[draw(st.integers(0, len(b) - 1))] = draw(st.integers(0, 255))
        return bytes(b)
    if kind == "random":
        return draw(st.binary(max_size=4000))
    return data


dims = st.tuples(st.integers(1, 4).map(lambda k: 2 * k), st.integers(1, 4), st.integers(1, 3),
                 st.integers(1, 4))  # n_samples (even), n_chirps, n_tx, n_rx


# ---------------------------------------------------------------------------------- DCA1000
def same_or_other(data, written: tuple[int, ...], other) -> tuple[int, ...]:
    """The profile written (most often) or another one."""
    return data.draw(st.one_of(st.just(written), st.just(written), other))


@given(data=st.data(), written=dims, n_frames=st.integers(1, 3),
       layout=st.sampled_from(["xwr16xx"] * 3 + ["xwr14xx"]), strict=st.booleans(),
       adc_bits=st.sampled_from([16] * 4 + [12, 14, None, 10]), seed=st.integers(0, 2**16))
def test_dca1000_headerless_fuzz(data, written, n_frames, layout, strict, adc_bits, seed):
    rng = np.random.default_rng(seed)
    ns, nc, nt, nr = written
    read = same_or_other(data, written, dims)
    with scratch() as d:
        path = Path(d) / "adc_data.bin"
        written_cube = codes(rng, (n_frames, nc, nt, nr, ns))
        write_dca1000(path, written_cube)
        original = path.read_bytes()
        path.write_bytes(mutate(original, data.draw))
        intact = path.read_bytes() == original
        with only_documented_outcomes(d):
            cube = read_dca1000(path, *read, layout=layout, strict=strict, adc_bits=adc_bits)
            check_cube(cube, read[1], read[2], read[3], read[0])
            if intact and read == written and layout == "xwr16xx" and adc_bits == 16:
                assert np.array_equal(cube, written_cube)


@given(data=st.data(), written=dims, n_frames=st.integers(1, 3),
       payload=st.integers(1, 40).map(lambda k: 2 * k), strict=st.booleans(),
       seed=st.integers(0, 2**16))
def test_dca1000_packets_fuzz(data, written, n_frames, payload, strict, seed):
    rng = np.random.default_rng(seed)
    read = same_or_other(data, written, dims)
    ns, nc, nt, nr = written
    cube = codes(rng, (n_frames, nc, nt, nr, ns))
    n = -(-cube.size * 4 // payload)
    order = data.draw(st.one_of(st.none(), st.permutations(range(n)),
                                st.lists(st.integers(0, n - 1), max_size=2 * n)))
    with scratch() as d:
        path = Path(d) / "adc_data_Raw_0.bin"
        write_dca1000_packets(path, cube, payload_bytes=payload, order=order)
        original = path.read_bytes()
        path.write_bytes(mutate(original, data.draw))
        intact = path.read_bytes() == original
        read_payload = data.draw(st.sampled_from([payload, payload, 1456, payload + 2]))
        with only_documented_outcomes(d):
            got, missing = read_dca1000_packets(path, *read, payload_bytes=read_payload,
                                                strict=strict)
            check_cube(got, read[1], read[2], read[3], read[0])
            assert missing.shape == got.shape and missing.dtype == bool
            assert not got[missing].any()
            if intact and order is None and read == written and read_payload == payload:
                assert np.array_equal(got, cube) and not missing.any()  # intact: exact


def test_dca1000_packets_reorder_and_loss_never_shift_a_sample():
    """Any loss, order and duplication of packets: every sample not masked is exact."""
    rng = np.random.default_rng(7)
    cube = codes(rng, (3, 4, 2, 4, 8))
    n = -(-cube.size * 4 // 48)

    @given(order=st.lists(st.integers(0, n - 1), min_size=n // 2, max_size=2 * n))
    def prop(order):
        with scratch() as d:
            path = write_dca1000_packets(Path(d) / "raw.bin", cube, payload_bytes=48,
                                         order=order)
            with only_documented_outcomes(d):
                cap = DCA1000PacketCapture(path, 8, 4, 2, 4, payload_bytes=48)
                got, missing = cap.read_masked()
                f = cap.frame_numbers
                assert np.array_equal(got[~missing], cube[f][~missing])
                assert not got[missing].any()

    prop()


# ---------------------------------------------------------------------------------- cascade
CASCADE_FILES = [f"{dev}_0000_{kind}.bin" for dev in ("master", "slave1", "slave2", "slave3")
                 for kind in ("data", "idx")]


@lru_cache(maxsize=None)
def cascade_files(n_frames: int, ns: int, nl: int, nt: int) -> tuple[dict[str, bytes],
                                                                      np.ndarray]:
    """The 8 files of a valid one-part cascade capture (written once per shape), its cube."""
    with scratch() as d:
        rng = np.random.default_rng(n_frames * 1000 + ns * 100 + nl * 10 + nt)
        cube = codes(rng, (n_frames, nl, nt, 16, ns))
        write_ti_cascade(d, cube, frame_period_s=0.1)
        return {name: (Path(d) / name).read_bytes() for name in CASCADE_FILES}, cube


cascade_dims = st.tuples(st.integers(1, 4), st.integers(1, 3), st.integers(1, 2))


@given(data=st.data(), n_frames=st.integers(1, 3), written=cascade_dims, skip=st.booleans(),
       part=st.sampled_from([None, None, 0, 1]))
def test_ti_cascade_fuzz(data, n_frames, written, skip, part):
    read = same_or_other(data, written, cascade_dims)
    original, written_cube = cascade_files(n_frames, *written)
    files = dict(original)
    for name in data.draw(st.lists(st.sampled_from(CASCADE_FILES), max_size=3, unique=True)):
        files[name] = mutate(files[name], data.draw)
    intact = files == original
    with scratch() as d:
        for name, content in files.items():
            (Path(d) / name).write_bytes(content)
        with only_documented_outcomes(d):
            cube = read_ti_cascade(d, *read, skip_first_frame=skip, part=part)
            check_cube(cube, read[1], read[2], 16, read[0])
            if intact and read == written:
                assert np.array_equal(cube, written_cube[int(skip):])


# ---------------------------------------------------------------------------------- OpenRadar
arrays = st.one_of(
    st.tuples(st.integers(1, 4), st.sampled_from([2, 4, 6, 8]), st.integers(1, 4),
              st.sampled_from([(0, 65535)] * 3 + [(-70000, 70000)])).flatmap(
        lambda spec: st.lists(st.integers(*spec[3]), min_size=2 * int(np.prod(spec[:3])),
                              max_size=2 * int(np.prod(spec[:3]))).map(
            lambda v: (np.array(v[::2], float) + 1j * np.array(v[1::2], float)).reshape(
                spec[:3]))),
    st.sampled_from([np.zeros((2, 3)), np.array([1.5 + 1j]), np.array([np.nan + 0j]),
                     np.zeros((0, 8, 4), complex), np.array(["a"]), np.arange(6).reshape(2, 3)]))


@given(data=st.data(), a=arrays, n_tx=st.sampled_from([1, 2, 2, 3]),
       unsigned=st.sampled_from([True, True, False]))
def test_openradar_npy_fuzz(data, a, n_tx, unsigned):
    with scratch() as d:
        path = Path(d) / "a.npy"
        np.save(path, a)
        path.write_bytes(mutate(path.read_bytes(), data.draw))
        with only_documented_outcomes(d):
            cube = read_openradar_npy(path, n_tx=n_tx, unsigned=unsigned)
            assert cube.dtype == np.complex64 and cube.ndim == 5 and cube.shape[2] == n_tx
            assert cube.shape[2] * cube.shape[3] == a.shape[1]
