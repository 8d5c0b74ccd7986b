"""Antenna geometry of TDM-MIMO radars: physical TX/RX positions and the virtual array.

Positions are kept in half-wavelength units at the array's design frequency, as TI's own cascade
code does, as ``(azimuth, elevation)`` pairs. A virtual element is a TX position plus an RX
position. The TX axis of a :class:`VirtualArray` is in *firing order* (the order of the cube's tx
axis, see ``RadarConfig.tx_order``); the RX axis is in file order.

For angle estimation in azimuth the elements at elevation 0 with distinct azimuth positions are
picked out as a uniform linear array (``ula_index``). On the MMWCAS cascade these are 86
contiguous positions.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from blindspot.arrays import checked_array
from blindspot.radar.config import RadarConfig
from blindspot.typed_config import ConfigError

# TI MMWCAS-RF-EVM, positions in units of lambda/2 at 76.8 GHz (TI cascade reference code).
# RX azimuth in file order: master RX1-4, slave1 RX5-8, slave2 RX9-12, slave3 RX13-16.
MMWCAS_RX_AZIMUTH = (11, 12, 13, 14, 50, 51, 52, 53, 46, 47, 48, 49, 0, 1, 2, 3)
# TI's reordering of the 16 file-order channels into its RX numbering (1-based).
MMWCAS_RX_ID = (13, 14, 15, 16, 1, 2, 3, 4, 9, 10, 11, 12, 5, 6, 7, 8)
# Physical TX1..TX12.
MMWCAS_TX_AZIMUTH = (11, 10, 9, 32, 28, 24, 20, 16, 12, 8, 4, 0)
MMWCAS_TX_ELEVATION = (6, 4, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0)
MMWCAS_DESIGN_FREQ_HZ = 76.8e9



class ArrayShapeError(ValueError):
    """Channel data whose TX/RX axes do not match the virtual array."""


@dataclass(frozen=True)
class VirtualArray:
    """A TDM-MIMO virtual array.

    Attributes
    ----------
    tx_pos : (n_tx, 2) int  TX (azimuth, elevation) in half-wavelength units, firing order.
    rx_pos : (n_rx, 2) int  RX (azimuth, elevation) in half-wavelength units, file order.
    spacing_wl : float      physical size of one unit in wavelengths at the operating frequency.
    """

    tx_pos: np.ndarray
    rx_pos: np.ndarray
    spacing_wl: float = 0.5

    @property
    def n_tx(self) -> int:
        return self.tx_pos.shape[0]

    @property
    def n_rx(self) -> int:
        return self.rx_pos.shape[0]

    @cached_property
    def virtual_pos(self) -> np.ndarray:
        """(n_tx, n_rx, 2) virtual element positions in half-wavelength units."""
        return self.tx_pos[:, None, :] + self.rx_pos[None, :, :]

    @cached_property
    def ula_index(self) -> tuple[np.ndarray, np.ndarray]:
        """(tx_idx, rx_idx), each (n_ula,): one virtual element per distinct azimuth position at
        elevation 0, sorted by azimuth (ties go to the earliest TX slot, then the earliest RX)."""
        az = self.virtual_pos[..., 0].ravel()
        el = self.virtual_pos[..., 1].ravel()
        flat = np.flatnonzero(el == 0)
        order = flat[np.lexsort((flat, az[flat]))]  # by azimuth, then by flat index
        _, first = np.unique(az[order], return_index=True)
        keep = order[first]
        return np.unravel_index(keep, (self.n_tx, self.n_rx))  # type: ignore[return-value]

    @property
    def n_ula(self) -> int:
        return len(self.ula_index[0])

    @cached_property
    def ula_positions_units(self) -> np.ndarray:
        """(n_ula,) azimuth of the ULA elements in half-wavelength units, ascending."""
        t, r = self.ula_index
        return self.virtual_pos[t, r, 0]

    @property
    def ula_positions_wl(self) -> np.ndarray:
        """(n_ula,) ULA element positions in wavelengths at the operating frequency."""
        return self.ula_positions_units * self.spacing_wl

    @property
    def ula_is_contiguous(self) -> bool:
        p = self.ula_positions_units
        return bool(np.all(np.diff(p) == 1))

    def ula_snapshots(self, x: np.ndarray) -> np.ndarray:
        """Pick the ULA channels out of an array whose axes (..., tx, rx, last) end as given:
        (..., n_tx, n_rx, L) -> (..., n_ula, L). Raises ArrayShapeError for other axes or a
        non-numeric array (values are not inspected: the angle estimator checks them)."""
        x = checked_array(x, "x", ArrayShapeError, where="ula_snapshots", kind="numeric",
                          finite=False, min_ndim=3, lengths={-3: self.n_tx, -2: self.n_rx},
                          axes=f"channels (..., tx={self.n_tx}, rx={self.n_rx}, L)")
        t, r = self.ula_index
        return x[..., t, r, :]


def mmwcas_array(tx_order: tuple[int, ...] | None = None, freq_hz: float = 77e9,
                 n_rx: int = 16) -> VirtualArray:
    """The TI MMWCAS cascade array, TX in ``tx_order`` (0-based physical TX, firing order)."""
    order = np.arange(12) if tx_order is None else np.asarray(tx_order, dtype=int)
    tx = np.stack([MMWCAS_TX_AZIMUTH, MMWCAS_TX_ELEVATION], axis=1)[order]
    rx = np.stack([MMWCAS_RX_AZIMUTH, np.zeros(16, dtype=int)], axis=1)[:n_rx]
    # d = lambda_design / 2, so in wavelengths at freq_hz: 0.5 * freq / f_design.
    return VirtualArray(tx_pos=tx, rx_pos=rx, spacing_wl=0.5 * freq_hz / MMWCAS_DESIGN_FREQ_HZ)


def ula_array(n_tx: int, n_rx: int, rx_spacing_wl: float = 0.5,
              tx_order: tuple[int, ...] | None = None) -> VirtualArray:
    """A generic TDM-MIMO array: RX spaced ``rx_spacing_wl`` apart, TX spaced n_rx RX spacings
    apart, so the virtual array is a filled ULA of n_tx * n_rx elements (e.g. AWR1843 2 TX x 4 RX)."""
    order = np.arange(n_tx) if tx_order is None else np.asarray(tx_order, dtype=int)
    tx = np.stack([np.arange(n_tx) * n_rx, np.zeros(n_tx, dtype=int)], axis=1)[order]
    rx = np.stack([np.arange(n_rx), np.zeros(n_rx, dtype=int)], axis=1)
    return VirtualArray(tx_pos=tx, rx_pos=rx, spacing_wl=rx_spacing_wl)


def array_for(radar: RadarConfig) -> VirtualArray:
    """The virtual array a radar profile names (``radar.array``), TX in its firing order."""
    if radar.array == "mmwcas":
        return mmwcas_array(radar.tx_order, freq_hz=radar.center_freq_hz, n_rx=radar.n_rx)
    if radar.array == "ula":
        return ula_array(radar.n_tx, radar.n_rx, radar.rx_spacing_wl, radar.tx_order)
    raise ConfigError("radar.array", radar.array, "'mmwcas' or 'ula'")
