"""Back-ends and layouts of the range-Doppler step, on one MMWCAS frame (64 x 12 x 16 x 256).

    PYTHONPATH=src python benchmarks/bench_fft.py [--threads 1] [--rounds 15] [--frame FILE.npz]
                                                  [--crop 61] [--batch 8] [--only WORD] [--json]

Times every way this machine's Python stack can do the step the detection chain needs
(windowed range FFT over samples, windowed Doppler FFT over chirps, zero Doppler centred,
optionally only the first ``n_range`` range bins Doppler-transformed) and the channel-summed
power map (``detection_map``), and prints a table of medians: wall-clock ms and CPU ms of the
calling thread (``time.thread_time``; with one thread all the work runs on the calling thread, so
this is the one-core cost even on a machine shared with other jobs).

The variants run round-robin (one call of each per round, ``--rounds`` rounds after two warm-up
rounds), so a change of load on a shared machine hits them all alike. Each result is checked
against a float64 numpy reference (``err``: max |X - X_ref| / max |X_ref|); a variant that
disagrees beyond float32 rounding is flagged.

Back-ends: ``numpy.fft`` (pocketfft C, float32 native since numpy 2), ``scipy.fft`` (pocketfft
C++, SIMD over several transforms, ``workers`` and ``overwrite_x``), ``torch.fft`` (CPU build:
MKL), FFTW through pyFFTW (plans ``FFTW_ESTIMATE`` and ``FFTW_MEASURE``; the whole frame in place,
or cache-sized blocks of channels that the window multiply writes and FFTW transforms into the
result: the chain's way, ``RangeDoppler.native``). Layouts: the cube's own ``(chirps, tx, rx, samples)`` order (the Doppler FFT then strides
by 12*16*256 elements) or channel-major ``(tx, rx, chirps, samples)`` (each channel's 64 x 256
block contiguous, 128 KiB, so both FFTs of a channel run in L2), the window multiply fused into
the copy that makes that layout. The input is complex baseband (I/Q), so no real-input (rfft)
shortcut applies to either FFT.

``--threads N`` pins numpy/BLAS/OpenMP (environment + threadpoolctl), scipy.fft (``workers``) and
torch (``set_num_threads``). With ``--json`` the last stdout line is
``{"rows": [{"group", "variant", "wall_ms", "cpu_ms", "err"}, ..]}``. ``--batch B`` adds
``RangeDoppler.native`` + ``detection_map`` on B copies of the frame at once (times per frame;
B = 64 needs about 5 GB of memory). Without ``--frame`` the frame is seeded white noise (FFT
speed does not depend on the content).
"""

from __future__ import annotations

import os
import sys

_THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
                "VECLIB_MAXIMUM_THREADS", "NUMEXPR_NUM_THREADS")


def _early_threads(argv: list[str]) -> None:
    """Export the pool-size variables before numpy/torch are imported (default: 1 thread)."""
    n = "1"
    for i, a in enumerate(argv):
        if a == "--threads" and i + 1 < len(argv):
            n = argv[i + 1]
        elif a.startswith("--threads="):
            n = a.split("=", 1)[1]
    for var in _THREAD_VARS:
        os.environ[var] = n


if __name__ == "__main__":
    _early_threads(sys.argv[1:])

import argparse  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import scipy.fft as sfft  # noqa: E402
import scipy.signal  # noqa: E402

SHAPE = (64, 12, 16, 256)  # MMWCAS frame: (chirps, tx, rx, samples)


def _windows(n_chirps: int, n_samples: int):
    """Hann range window (samples,) f32; Hann Doppler window times the zero-centring modulation
    (chirps,) c64; their product (chirps, samples) c64."""
    wr = scipy.signal.get_window("hann", n_samples, fftbins=True)
    c = np.arange(n_chirps)
    wd = scipy.signal.get_window("hann", n_chirps, fftbins=True) * np.exp(
        2j * np.pi * c * (n_chirps // 2) / n_chirps)
    return wr.astype(np.float32), wd.astype(np.complex64), (wd[:, None] * wr).astype(np.complex64)


def reference(cube: np.ndarray) -> np.ndarray:
    """float64 numpy reference: complex128 (doppler, tx, rx, range), zero Doppler centred."""
    wr = scipy.signal.get_window("hann", cube.shape[-1], fftbins=True)
    wd = scipy.signal.get_window("hann", cube.shape[0], fftbins=True)
    x = np.fft.fft(cube.astype(np.complex128) * wr, axis=-1)
    x = np.fft.fft(x * wd[:, None, None, None], axis=0)
    return np.fft.fftshift(x, axes=0)


def variants(cube: np.ndarray, threads: int, n_crop: int):
    """(group, name, fn) triples; fn() returns the result as (doppler, tx, rx, range) (any
    strides; cropped variants: range cut to ``n_crop``) or, for maps, (range, doppler)."""
    import torch

    from blindspot.dsp.range_doppler import RangeDoppler, detection_map

    c, t, r, n = cube.shape
    wr, wd, w2d = _windows(c, n)
    w4 = w2d[:, None, None, :]                       # (chirps, 1, 1, samples)
    wcm = w2d[None, None]                            # (1, 1, chirps, samples) channel-major
    cube_cm = cube.transpose(1, 2, 0, 3)             # (tx, rx, chirps, samples) view
    tcube = torch.from_numpy(cube)
    tw4, twcm = torch.from_numpy(w4), torch.from_numpy(np.ascontiguousarray(wcm))
    tbuf = torch.empty((t, r, c, n), dtype=torch.complex64)
    tout = torch.empty((t, r, c, n), dtype=torch.complex64)
    w = threads
    out: list[tuple[str, str, Callable[[], np.ndarray]]] = []

    def add(group: str, name: str):
        def deco(fn):
            out.append((group, name, fn))
            return fn
        return deco

    # ---- the pieces ------------------------------------------------------------------------
    @add("pieces", "window multiply, cube order (c64 out)")
    def _():
        return np.multiply(cube, w4, dtype=np.complex64)

    @add("pieces", "window multiply into channel-major (tx,rx,c,n)")
    def _():
        return np.multiply(cube_cm, wcm, dtype=np.complex64)

    @add("pieces", "torch window multiply into channel-major")
    def _():
        return torch.mul(tcube.permute(1, 2, 0, 3), twcm, out=tbuf).numpy()

    @add("pieces", "scipy range FFT only (cube order, in place)")
    def _():
        x = np.multiply(cube, wr, dtype=np.complex64)
        return sfft.fft(x, axis=-1, overwrite_x=True, workers=w)

    @add("pieces", "torch range FFT only (channel-major)")
    def _():
        torch.mul(tcube.permute(1, 2, 0, 3), torch.from_numpy(wr), out=tbuf)
        return torch.fft.fft(tbuf, dim=-1, out=tout).numpy()

    # ---- full range: both FFTs ------------------------------------------------------------
    @add("full range", "numpy.fft c64, cube order, out= in place")
    def _():
        x = np.multiply(cube, w4, dtype=np.complex64)
        np.fft.fft(x, axis=-1, out=x)
        return np.fft.fft(x, axis=0, out=x)

    @add("full range", "scipy.fft c64, cube order, in place (chain before)")
    def _():
        x = np.multiply(cube, w4, dtype=np.complex64)
        sfft.fft(x, axis=3, overwrite_x=True, workers=w)
        return sfft.fft(x, axis=0, overwrite_x=True, workers=w)

    @add("full range", "scipy.fft fft2 axes (0,3), cube order, in place")
    def _():
        x = np.multiply(cube, w4, dtype=np.complex64)
        return sfft.fft2(x, axes=(0, 3), overwrite_x=True, workers=w)

    @add("full range", "scipy.fft c64, channel-major, in place")
    def _():
        x = np.multiply(cube_cm, wcm, dtype=np.complex64)
        return sfft.fft2(x, axes=(2, 3), overwrite_x=True, workers=w).transpose(2, 0, 1, 3)

    @add("full range", "scipy.fft c128, cube order, in place")
    def _():
        x = np.multiply(cube, w4, dtype=np.complex128)
        sfft.fft(x, axis=3, overwrite_x=True, workers=w)
        return sfft.fft(x, axis=0, overwrite_x=True, workers=w)

    @add("full range", "scipy.fft c64, cache blocks of 4 channels (Python loop)")
    def _():
        k = 4
        buf = np.empty((t, r // k, c, k, n), np.complex64)
        for i in range(t):
            for j in range(r // k):
                b = buf[i, j]
                np.multiply(cube[:, i, j * k:(j + 1) * k], w2d[:, None, :], out=b)
                sfft.fft2(b, axes=(0, 2), overwrite_x=True, workers=w)
        return buf.transpose(2, 0, 1, 3, 4).reshape(c, t, r, n)

    @add("full range", "torch.fft c64, cube order, fft2 dim (0,3)")
    def _():
        return torch.fft.fft2(tcube * tw4, dim=(0, 3)).numpy()

    @add("full range", "torch.fft c64, cube order, range then Doppler")
    def _():
        x = torch.fft.fft(tcube * tw4, dim=3)
        return torch.fft.fft(x, dim=0).numpy()

    @add("full range", "torch.fft c64, channel-major, fft2 (fresh output)")
    def _():
        torch.mul(tcube.permute(1, 2, 0, 3), twcm, out=tbuf)
        return torch.fft.fft2(tbuf, dim=(2, 3)).numpy().transpose(2, 0, 1, 3)

    @add("full range", "torch.fft c64, channel-major, fft2 out= reused")
    def _():
        torch.mul(tcube.permute(1, 2, 0, 3), twcm, out=tbuf)
        return torch.fft.fft2(tbuf, dim=(2, 3), out=tout).numpy().transpose(2, 0, 1, 3)

    @add("full range", "torch.fft c64, channel-major, range then Doppler")
    def _():
        torch.mul(tcube.permute(1, 2, 0, 3), twcm, out=tbuf)
        x = torch.fft.fft(tbuf, dim=3)
        return torch.fft.fft(x, dim=2).numpy().transpose(2, 0, 1, 3)

    @add("full range", "torch.fft c128, channel-major, fft2")
    def _():
        x = tcube.permute(1, 2, 0, 3).to(torch.complex128) * twcm
        return torch.fft.fft2(x, dim=(2, 3)).numpy().transpose(2, 0, 1, 3)

    # FFTW (pyFFTW): plans made once here (FFTW_ESTIMATE: no timing runs, deterministic; and
    # FFTW_MEASURE: timed planning, which may pick another algorithm in another process)
    import pyfftw

    def fftw_plan(shape, axes, flag, in_place=True):
        a = pyfftw.empty_aligned(shape, dtype=np.complex64, n=64)
        b = a if in_place else pyfftw.empty_aligned(shape, dtype=np.complex64, n=64)
        flags = (flag,) if in_place else (flag, "FFTW_DESTROY_INPUT")
        return pyfftw.FFTW(a, b, axes=axes, flags=flags, threads=w)

    for flag in ("FFTW_ESTIMATE", "FFTW_MEASURE"):
        whole = fftw_plan((t, r, c, n), (2, 3), flag)

        @add("full range", f"fftw {flag[5:].lower()}: channel-major, fft2 in place")
        def _(p=whole):
            np.multiply(cube_cm, wcm, out=p.input_array)
            p.execute()
            return p.output_array.transpose(2, 0, 1, 3)

        rng_p, dop_p = fftw_plan((t, r, c, n), (3,), flag), fftw_plan((t, r, c, n), (2,), flag)
        dop_p.update_arrays(rng_p.input_array, rng_p.input_array)

        @add("full range", f"fftw {flag[5:].lower()}: channel-major, range then Doppler")
        def _(p1=rng_p, p2=dop_p):
            np.multiply(cube_cm, wcm, out=p1.input_array)
            p1.execute()
            p2.execute()
            return p1.output_array.transpose(2, 0, 1, 3)

        for k in (1, 2, 4, 8, 32):
            blk = fftw_plan((k, c, n), (1, 2), flag, in_place=False)
            res = pyfftw.empty_aligned((t * r, c, n), dtype=np.complex64, n=64)
            src = np.moveaxis(cube.reshape(c, t * r, n), 0, 1)  # (channels, c, n) view

            @add("full range", f"fftw {flag[5:].lower()}: blocks of {k} channels, window "
                               "into block")
            def _(p=blk, k=k, res=res, src=src):
                for c0 in range(0, t * r, k):
                    np.multiply(src[c0:c0 + k], w2d, out=p.input_array)
                    p.update_arrays(p.input_array, res[c0:c0 + k])
                    p.execute()
                return res.reshape(t, r, c, n).transpose(2, 0, 1, 3)

    rd_full = RangeDoppler(c, n, "hann", "hann", w, None)

    @add("full range", "RangeDoppler.native (this checkout)")
    def _():
        return rd_full.native(cube)

    # ---- range cut before the Doppler FFT -------------------------------------------------
    @add(f"range cut {n_crop}", "scipy cube order: range FFT, cut, Doppler (chain before)")
    def _():
        x = np.multiply(cube, wr, dtype=np.complex64)
        sfft.fft(x, axis=3, overwrite_x=True, workers=w)
        y = np.multiply(x[..., :n_crop], wd[:, None, None, None], dtype=np.complex64)
        return sfft.fft(y, axis=0, overwrite_x=True, workers=w)

    @add(f"range cut {n_crop}", "scipy channel-major: range FFT, cut, Doppler")
    def _():
        x = np.multiply(cube_cm, wcm, dtype=np.complex64)
        sfft.fft(x, axis=3, overwrite_x=True, workers=w)
        return sfft.fft(x[..., :n_crop], axis=2, workers=w).transpose(2, 0, 1, 3)

    @add(f"range cut {n_crop}", "torch channel-major: range FFT, cut, Doppler")
    def _():
        torch.mul(tcube.permute(1, 2, 0, 3), twcm, out=tbuf)
        x = torch.fft.fft(tbuf, dim=3, out=tout)[..., :n_crop]
        return torch.fft.fft(x, dim=2).numpy().transpose(2, 0, 1, 3)

    @add(f"range cut {n_crop}", "torch channel-major: range FFT, cut copy, Doppler")
    def _():
        torch.mul(tcube.permute(1, 2, 0, 3), twcm, out=tbuf)
        x = torch.fft.fft(tbuf, dim=3, out=tout)[..., :n_crop].contiguous()
        return torch.fft.fft(x, dim=2).numpy().transpose(2, 0, 1, 3)

    @add(f"range cut {n_crop}", "torch channel-major: fft2 then cut (no saving)")
    def _():
        torch.mul(tcube.permute(1, 2, 0, 3), twcm, out=tbuf)
        return torch.fft.fft2(tbuf, dim=(2, 3), out=tout)[..., :n_crop].numpy().transpose(
            2, 0, 1, 3)

    rd_cut = RangeDoppler(c, n, "hann", "hann", w, n_crop)

    @add(f"range cut {n_crop}", "RangeDoppler.native (this checkout)")
    def _():
        return rd_cut.native(cube)

    # ---- the power map ----------------------------------------------------------------------
    rd_cube_order = reference(cube).astype(np.complex64)               # (doppler, tx, rx, range)
    rd_cm = np.ascontiguousarray(rd_cube_order.transpose(1, 2, 0, 3))  # (tx, rx, doppler, range)
    f_cm = rd_cm.view(np.float32).reshape(t * r, -1)
    t_cm = torch.from_numpy(rd_cm)

    @add("map", "square + sum, cube order (chain before)")
    def _():
        f = rd_cube_order.view(np.float32).reshape(c, t * r, 2 * n)
        s = np.square(f).sum(axis=1)
        return s.reshape(c, n, 2).sum(axis=2, dtype=np.float64).T

    @add("map", "square + sum over channels, channel-major")
    def _():
        s = np.square(f_cm).sum(axis=0).reshape(c, n, 2)
        return s.sum(axis=2, dtype=np.float64).T

    @add("map", "einsum over channels, channel-major")
    def _():
        s = np.einsum("ck,ck->k", f_cm, f_cm).reshape(c, n, 2)
        return s.sum(axis=2, dtype=np.float64).T

    @add("map", "torch |x|^2 sum, channel-major")
    def _():
        return (t_cm.abs() ** 2).sum(dim=(0, 1)).numpy().astype(np.float64).T

    rd_native = rd_full.native(cube)

    @add("map", "detection_map (this checkout), its native layout")
    def _():
        return detection_map(np.moveaxis(rd_native, 3, 0))

    return out


def _time(fn: Callable[[], object]) -> tuple[float, float]:
    c0, t0 = time.thread_time(), time.perf_counter()
    fn()
    return (time.perf_counter() - t0) * 1e3, (time.thread_time() - c0) * 1e3


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--rounds", type=int, default=15)
    ap.add_argument("--frame", type=Path,
                    help="npz with 'cube' complex64 (chirps, tx, rx, samples)")
    ap.add_argument("--crop", type=int, default=61, help="range bins kept in the cut variants "
                    "(61 = the paper's 30 m window)")
    ap.add_argument("--batch", type=int, default=0,
                    help="also time RangeDoppler.native + detection_map on this many frames")
    ap.add_argument("--only", default=None, help="run only variants whose name or group has WORD")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)

    import torch
    from threadpoolctl import threadpool_limits

    torch.set_num_threads(args.threads)
    if args.frame is not None:
        with np.load(args.frame) as z:
            cube = z["cube"].astype(np.complex64)
        label = str(args.frame)
    else:
        rng = np.random.default_rng(0)
        cube = (rng.standard_normal(SHAPE, np.float32)
                + 1j * rng.standard_normal(SHAPE, np.float32)).astype(np.complex64)
        label = "white noise, seed 0"
    ref = reference(cube)
    ref_map = (np.abs(ref) ** 2).sum(axis=(1, 2)).T      # (range, doppler)
    runs = variants(cube, args.threads, args.crop)
    if args.only:
        runs = [v for v in runs if args.only.lower() in (v[0] + v[1]).lower()]

    per_frame = {}
    if args.batch:
        from blindspot.dsp.range_doppler import RangeDoppler, detection_map

        batch = np.broadcast_to(cube, (args.batch, *cube.shape)).copy()
        rd1 = RangeDoppler(cube.shape[0], cube.shape[-1], "hann", "hann", args.threads)
        rdc = RangeDoppler(cube.shape[0], cube.shape[-1], "hann", "hann", args.threads, args.crop)
        group = f"batch of {args.batch}"
        runs.append((group, "native + detection_map, one frame", lambda: detection_map(
            np.moveaxis(rd1.native(cube), -1, -4))))
        runs.append((group, "native + detection_map, the batch, per frame", lambda: detection_map(
            np.moveaxis(rd1.native(batch), -1, -4))[-1]))
        per_frame[group, "native + detection_map, the batch, per frame"] = args.batch
        runs.append((group, f"range cut {args.crop}: the batch, per frame", lambda: detection_map(
            np.moveaxis(rdc.native(batch), -1, -4))[-1]))
        per_frame[group, f"range cut {args.crop}: the batch, per frame"] = args.batch

    errs = {}
    with threadpool_limits(limits=args.threads):
        for group, name, fn in runs:
            res = np.asarray(fn())
            if group == "map" or group.startswith("batch"):
                want = ref_map[:res.shape[0]]
                e = float(np.abs(res - want).max() / want.max())
            elif group.startswith("range cut"):
                want = ref[..., :args.crop]
                e = float(np.abs(res - want).max() / np.abs(want).max())
            elif group == "pieces":
                e = float("nan")
            else:
                e = float(np.abs(res - ref).max() / np.abs(ref).max())
            errs[name, group] = e
        for _ in range(2):  # warm-up rounds
            for _, _, fn in runs:
                fn()
        times: dict[tuple[str, str], list[tuple[float, float]]] = {
            (n, g): [] for g, n, _ in runs}
        for _ in range(args.rounds):
            for group, name, fn in runs:
                times[name, group].append(_time(fn))

    print(f"frame: {label} {cube.shape} complex64; threads {args.threads}; {args.rounds} rounds; "
          f"load average {os.getloadavg()[0]:.2f}; numpy {np.__version__}, "
          f"scipy {__import__('scipy').__version__}, torch {torch.__version__} "
          f"(MKL {torch.backends.mkl.is_available()})")
    print(f"{'group':<14s} {'variant':<58s} {'wall ms':>8s} {'CPU ms':>8s} {'err':>9s}")
    rows = []
    for group, name, _ in runs:
        k = per_frame.get((group, name), 1)
        wall = float(np.median([x[0] for x in times[name, group]])) / k
        cpu = float(np.median([x[1] for x in times[name, group]])) / k
        e = errs[name, group]
        flag = "  <- WRONG" if e > 1e-5 else ""
        print(f"{group:<14s} {name:<58s} {wall:8.2f} {cpu:8.2f} {e:9.1e}{flag}")
        rows.append({"group": group, "variant": name, "wall_ms": wall, "cpu_ms": cpu, "err": e})
    if args.json:
        print(json.dumps({"rows": rows}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
