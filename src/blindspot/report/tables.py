"""The paper's tables as Markdown, our values beside the paper's.

Tables take plain values (configs and metrics read from the pipeline's artifacts); they compute
no science of their own. The paper's column is read from :mod:`blindspot.report.paper_values`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

from blindspot.radar.config import RadarConfig
from blindspot.report import paper_values as paper


def markdown_table(header: Sequence[str], rows: Sequence[Sequence[Any]]) -> str:
    """A GitHub-flavoured Markdown table; floats printed with 4 significant digits."""
    def cell(v: Any) -> str:
        if isinstance(v, float):
            return "n/a" if math.isnan(v) else f"{v:.4g}"
        return "" if v is None else str(v)

    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(cell(v) for v in row) + " |" for row in rows]
    return "\n".join(lines) + "\n"


def _with_unit(value: paper.PaperValue) -> str:
    """"77 GHz": a paper value and its unit as the paper writes them."""
    return f"{value.value:g} {value.unit}"


def table2_radar(radar: RadarConfig) -> str:
    """Table 2 (radar parameters): the paper's values, ours, and what the paper does not state."""
    s = radar.summary()
    rows = [
        ("Centre frequency", _with_unit(paper.CENTRE_FREQUENCY_GHZ), f"{s['center_freq_ghz']:.3f} GHz"),
        ("Bandwidth", _with_unit(paper.BANDWIDTH_MHZ), f"{radar.bandwidth_hz / 1e6:g} MHz"),
        ("Chirp duration", _with_unit(paper.CHIRP_DURATION_US), f"{radar.ramp_time_s * 1e6:g} us"),
        ("Chirps (loops) per frame", f"{paper.N_CHIRPS.value}", f"{radar.n_chirps}"),
        ("Samples per chirp", f"{paper.N_SAMPLES.value}", f"{radar.n_samples}"),
        ("TX / RX elements", f"{paper.N_TX.value} / {paper.N_RX.value}", f"{radar.n_tx} / {radar.n_rx}"),
        ("ADC rate", "not stated", f"{radar.adc_rate_hz / 1e6:.4g} Msps"),
        ("Idle time", "not stated", f"{radar.idle_time_s * 1e6:g} us"),
        ("Frame period", "not stated", f"{radar.frame_period_s * 1e3:g} ms"),
        ("TX firing order (0-based)", "not stated", " ".join(map(str, radar.tx_order))),
        ("Noise figure", "not stated", f"{radar.noise_figure_db:g} dB"),
        ("TX power, TX/RX antenna gain", "not stated",
         f"{radar.tx_power_dbm:g} dBm, {radar.tx_gain_dbi:g}/{radar.rx_gain_dbi:g} dBi"),
        ("Slope (derived)", _with_unit(paper.SLOPE_MHZ_PER_US), f"{s['slope_mhz_per_us']:.4g} MHz/us"),
        ("Range resolution (derived)", _with_unit(paper.RANGE_RESOLUTION_M), f"{s['range_resolution_m']:.4g} m"),
        ("Maximum range (derived)", "not stated", f"{s['max_range_m']:.4g} m"),
        ("Velocity resolution (derived, TDM over all TX)", "not stated",
         f"{s['velocity_resolution_mps']:.4g} m/s"),
        ("Max. unambiguous velocity (derived)", "not stated", f"{s['max_velocity_mps']:.4g} m/s"),
    ]
    return ("## Table 2: radar parameters (TI MMWCAS-RF-EVM)\n\n"
            + markdown_table(("parameter", "paper", "ours"), rows))


def table1_lstm(model: Mapping[str, Any], train: Mapping[str, Any], counts: Mapping[str, int],
                val_rmse_m: float, test_rmse_m: float | None = None,
                baselines: Mapping[str, float] | None = None,
                member_val_rmse_m: Mapping[int, float] | None = None) -> str:
    """Table 1 (LSTM hyper-parameters and validation RMSE), paper beside ours.

    baselines: validation RMSE of other predictors on the same windows, e.g. {"constant velocity": ..}.
    member_val_rmse_m: validation RMSE of each member of a seed ensemble, by seed (a row with
        their range, what a single training run would have given).
    """
    rows: list[tuple[Any, ...]] = [
        ("Window size", paper.WINDOW.value, model.get("window", counts.get("window"))),
        ("Training pairs", f"{paper.TRAIN_PAIRS.value:,}", f"{counts['train']:,}"),
        ("Validation pairs", f"{paper.VAL_PAIRS.value:,}", f"{counts['val']:,}"),
        ("Test pairs", f"{paper.TEST_PAIRS.value:,}", f"{counts['test']:,}"),
        ("Validation RMSE", f"{paper.VAL_RMSE.value} (units not stated)", f"{val_rmse_m:.4f} m"),
        ("Learning rate", paper.LEARNING_RATE.value, train["lr"]),
        ("Activation", paper.ACTIVATION.value, f"{model.get('head_activation', 'relu')} (head); tanh inside the LSTM cell"),
        ("Optimiser", paper.OPTIMISER.value, str(train.get("optimizer", "adam")).capitalize()),
        ("Epochs", paper.EPOCHS.value, train["epochs"]),
        ("Hidden size / layers", "not stated", f"{model.get('hidden_size')} / {model.get('num_layers')}"),
        ("Batch size", "not stated", train.get("batch_size")),
        ("Target", "not stated", model.get("target")),
    ]
    if test_rmse_m is not None:
        rows.insert(5, ("Test RMSE", "not stated", f"{test_rmse_m:.4f} m"))
    if member_val_rmse_m and len(member_val_rmse_m) > 1:
        v = list(member_val_rmse_m.values())
        rows.insert(5, (f"Validation RMSE, each of {len(v)} seeds alone", "one run",
                        f"{min(v):.4f} - {max(v):.4f} m (seeds {min(member_val_rmse_m)}-"
                        f"{max(member_val_rmse_m)}; the row above is their ensemble)"))
        rows.append(("Seed ensemble", "not stated", f"{len(v)} networks, next points averaged"))
    for name, value in (baselines or {}).items():
        rows.append((f"Validation RMSE, {name}", "not reported", f"{value:.4f} m"))
    return ("## Table 1: LSTM hyper-parameters\n\n"
            + markdown_table(("parameter", "paper", "ours"), rows))
