"""The paper's reference values, and the published ETH/UCY numbers, in one place.

Every number of the paper that the pipeline prints beside its own (tables, figures, the report
page, the metrics files of the stages) is read from here; none is typed anywhere else. Each
value names where the paper states it, as a place in ``paper/PAPER.md`` (the English digest of
the paper, beside ``../shared/DESIGN.md``): a table, a figure, a numbered step of "Method, step by
step", a section, or the "Headline numbers" table. ``tests/report/test_paper_values.py`` checks
that every value is written in the digest.

Values keep the paper's units (GHz, MHz, us where the paper writes them) so the tables print
them as the paper does; :attr:`PaperValue.unit` says which. Where the paper does not state the
unit (the validation RMSE), the unit is empty and the note says so.

The ETH/UCY numbers are not the paper's: they are the literature's (Schöller et al. 2020 and
the baselines of the data set's README, ``shared/data/ethucy/README.md``), printed beside our
ETH/UCY benchmark.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = [
    "PaperValue",
    "WINDOW",
    "TRAIN_PAIRS",
    "VAL_PAIRS",
    "TEST_PAIRS",
    "VAL_RMSE",
    "LEARNING_RATE",
    "ACTIVATION",
    "OPTIMISER",
    "EPOCHS",
    "CENTRE_FREQUENCY_GHZ",
    "BANDWIDTH_MHZ",
    "CHIRP_DURATION_US",
    "N_CHIRPS",
    "N_SAMPLES",
    "N_TX",
    "N_RX",
    "SLOPE_MHZ_PER_US",
    "RANGE_RESOLUTION_M",
    "FIG6E_ACCUMULATED_FRAMES",
    "PATH_ERROR_MEAN_M",
    "PATH_ERROR_FIRST_BELOW_M",
    "ALL",
    "ETHUCY_CVM",
    "ETHUCY_PUBLISHED",
]


@dataclass(frozen=True)
class PaperValue:
    """A value the paper states, and where.

    Attributes:
        value: the number (or word) as the paper gives it.
        unit: its unit as the paper writes it after the number ("" for a count the paper
            writes without one, a plain number, or a unit not stated).
        source: where ``paper/PAPER.md`` states it (table, figure, method step, section).
        note: what the paper leaves open about it, if anything.
    """

    value: float | int | str
    unit: str
    source: str
    note: str = ""


# ---------------------------------------------------------------- Table 1 (simulation, section III)

WINDOW = PaperValue(50, "points", "Table 1; section III (Simulation); method step 8")
"""Input window of the many-to-one LSTM: 50 points predict the next one."""

TRAIN_PAIRS = PaperValue(20_000, "", "Table 1; section III (Simulation)")
"""Training window/response pairs."""

VAL_PAIRS = PaperValue(4_000, "", "Table 1; section III (Simulation)")
"""Validation pairs."""

TEST_PAIRS = PaperValue(500, "", "section III (Simulation)",
                        "not in Table 1; outside train and validation")
"""Test pairs."""

VAL_RMSE = PaperValue(0.07, "", "Table 1; Headline numbers",
                      "units not stated (we read metres, RMSE over both coordinates)")
"""One-step validation RMSE of the LSTM on the simulated windows."""

LEARNING_RATE = PaperValue(0.001, "", "Table 1")
"""Adam's learning rate."""

ACTIVATION = PaperValue("ReLU", "", "Table 1")
"""Activation."""

OPTIMISER = PaperValue("Adam", "", "Table 1")
"""Optimiser."""

EPOCHS = PaperValue(15, "epochs", "Table 1")
"""Training epochs."""

# ---------------------------------------------------------------- Table 2 (radar, section IV)

CENTRE_FREQUENCY_GHZ = PaperValue(77, "GHz", "Table 2")
"""Centre frequency."""

BANDWIDTH_MHZ = PaperValue(300, "MHz", "Table 2")
"""Swept bandwidth."""

CHIRP_DURATION_US = PaperValue(30, "us", "Table 2")
"""Chirp duration."""

N_CHIRPS = PaperValue(64, "", "Table 2")
"""Total number of chirps (chirp loops per frame)."""

N_SAMPLES = PaperValue(256, "", "Table 2")
"""Time samples per chirp."""

N_TX = PaperValue(12, "TX", "Table 2; section IV (Real experiment)")
"""Transmit elements of the MMWCAS-RF-EVM."""

N_RX = PaperValue(16, "RX", "Table 2; section IV (Real experiment)")
"""Receive elements of the MMWCAS-RF-EVM."""

SLOPE_MHZ_PER_US = PaperValue(10, "MHz/us", "section IV, under Table 2",
                              "derived from Table 2 (300 MHz / 30 us), not stated")
"""Chirp slope."""

RANGE_RESOLUTION_M = PaperValue(0.5, "m", "section IV, under Table 2",
                                "derived from Table 2 (c / 2B), not stated")
"""Range resolution."""

# ---------------------------------------------------------------- figures (section IV)

FIG6E_ACCUMULATED_FRAMES = PaperValue(100, "frames", "Fig. 6e; method step 7")
"""Frames of pedestrian points accumulated in Fig. 6e."""

PATH_ERROR_MEAN_M = PaperValue(0.09, "m", "Fig. 10; method step 11; Headline numbers")
"""Mean Euclidean error of the predicted path: each predicted point's distance to the nearest
point of the actual path (real data)."""

PATH_ERROR_FIRST_BELOW_M = PaperValue(0.1, "m", "method step 11; Headline numbers",
                                      "an upper bound: early predictions are below it")
"""Bound on the error at the start of the prediction."""

ALL: dict[str, PaperValue] = {
    name: value for name, value in globals().items() if isinstance(value, PaperValue)
}
"""Every value above by its name (for checks and listings)."""

# ---------------------------------------------------------------- ETH/UCY (not the paper's)

ETHUCY_PUBLISHED: dict[str, dict[str, dict[str, float]]] = {
    "cvm (Schöller et al. 2020)": {
        "eth": {"ade": 1.00, "fde": 2.23}, "hotel": {"ade": 0.32, "fde": 0.62},
        "univ": {"ade": 0.52, "fde": 1.17}, "zara1": {"ade": 0.43, "fde": 0.96},
        "zara2": {"ade": 0.33, "fde": 0.73}, "avg": {"ade": 0.52, "fde": 1.14},
    },
    "linear": {"avg": {"ade": 0.79, "fde": 1.59}},
    "vanilla LSTM": {"avg": {"ade": 0.70, "fde": 1.52}},
    "Social-LSTM": {"avg": {"ade": 0.72, "fde": 1.54}},
    "Trajectron++ (deterministic, fixed preprocessing)": {"avg": {"ade": 0.52, "fde": 1.11}},
}
"""Published ETH/UCY ADE/FDE (m), observe 8 predict 12, from ``shared/data/ethucy/README.md``;
per fold where the README gives them, ``avg`` the unweighted mean of the five folds."""

ETHUCY_CVM: dict[str, float] = ETHUCY_PUBLISHED["cvm (Schöller et al. 2020)"]["avg"]
"""The constant-velocity model's published average (Schöller et al. 2020, "What the constant
velocity model can teach us about pedestrian motion prediction"): ``{"ade", "fde"}`` in m."""
