"""Speed of the capture readers: prints figures, asserts nothing.

    .venv/bin/python benchmarks/bench_capture.py [--frames N] [--repeat R]

Writes an N-frame MMWCAS capture (paper profile: 64 loops x 12 TX x 16 RX x 256 samples,
25.2 MB per frame over the 4 device files) to a temporary folder, then times one lazy frame
read through ``TICascadeRecording.frame`` and the whole-capture ``read_ti_cascade``; and, when
the shared recording is present, ``read_dca1000`` on the real AWR1843 file.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np
from omegaconf import OmegaConf

from blindspot.radar.capture import (
    TICascadeRecording,
    read_dca1000,
    read_ti_cascade,
    write_ti_cascade,
)
from blindspot.radar.config import RadarConfig

REPO = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("BLINDSPOT_SHARED", REPO.parent / "shared"))


def median_ms(fn, repeat: int) -> float:
    fn()  # warm-up (page cache, memmap)
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return 1e3 * float(np.median(times))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=6)
    ap.add_argument("--repeat", type=int, default=7)
    args = ap.parse_args()
    radar = RadarConfig.from_mapping(OmegaConf.load(REPO / "conf/radar/mmwcas.yaml"))
    shape = (radar.n_chirps, radar.n_tx, radar.n_rx, radar.n_samples)
    rng = np.random.default_rng(0)
    frames = (
        (rng.integers(-2048, 2048, shape) + 1j * rng.integers(-2048, 2048, shape)).astype(
            np.complex64)
        for _ in range(args.frames)
    )
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        write_ti_cascade(tmp, frames, frame_period_s=radar.frame_period_s)
        write_s = time.perf_counter() - t0
        mb = args.frames * np.prod(shape) * 4 / 1e6
        print(f"write_ti_cascade: {args.frames} frames ({mb:.0f} MB) in {write_s * 1e3:.0f} ms "
              "(includes generating the random frames)")
        src = TICascadeRecording(tmp, radar)
        ms = median_ms(lambda: src.frame(src.n_frames // 2), args.repeat)
        print(f"TICascadeRecording.frame: {ms:.1f} ms per MMWCAS frame "
              f"({np.prod(shape) * 4 / 1e6 / ms:.2f} GB/s of int16 file data)")
        ms = median_ms(lambda: read_ti_cascade(tmp, radar.n_samples, radar.n_chirps,
                                                     radar.n_tx),
                       max(1, args.repeat // 2))
        print(f"read_ti_cascade: {ms:.0f} ms for {src.n_frames} frames "
              f"({ms / src.n_frames:.1f} ms per frame)")
    dca = SHARED / "data/radar/dca1000-awr1843/adc_data.bin"
    if dca.is_file():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ms = median_ms(lambda: read_dca1000(dca, 128, 255, 2, 4), args.repeat)
        print(f"read_dca1000: {ms:.1f} ms for the real AWR1843 file (4 frames, 4.2 MB)")
    else:
        print(f"read_dca1000: skipped, {dca} not found")


if __name__ == "__main__":
    main()
