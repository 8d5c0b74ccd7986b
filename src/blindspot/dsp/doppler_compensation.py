"""TDM-MIMO Doppler compensation.

In a TDM-MIMO frame TX slot ``k`` of every chirp loop fires ``t_k`` after the loop start
(``RadarConfig.tx_slot_times_s()``, ``k * T_chirp``). A target with Doppler frequency
``f_d = 2 v / lambda`` therefore adds the phase ``2 pi f_d t_k`` to every virtual channel of TX
slot k, on top of its spatial phase. Across the virtual array this is a phase pattern that the
angle estimator would read as a shifted (and distorted) direction; it must be removed before
angle estimation, using the target's Doppler as measured by the Doppler FFT:

    f_d = (bin - n_doppler // 2) / (n_doppler * T_loop)

for a zero-centred (fftshift-ordered) Doppler axis with ``T_loop = n_tx * T_chirp`` the time
between two chirps of one TX. The correction for channel (k, r) is ``exp(-j 2 pi f_d t_k)``.

Limits: the Doppler FFT sees velocities modulo ``2 v_max``; for a target faster than ``v_max`` the
bin is aliased and the correction is wrong by ``2 pi m t_k / T_loop`` (m = the unknown number of
wraps). Pedestrians (up to ~2 m/s) stay below the MMWCAS profile's 2.3 m/s.
"""

from __future__ import annotations

import numpy as np

from blindspot.arrays import checked_array
from blindspot.dsp.range_doppler import signed_doppler_index


class CompensationError(ValueError):
    """Channels, Doppler bins or slot times of the wrong shape or kind, or not finite."""


def doppler_frequency_hz(doppler_bin: np.ndarray | int, n_doppler: int,
                         loop_period_s: float) -> np.ndarray:
    """Doppler frequency (Hz) of zero-centred Doppler bins (any shape)."""
    return signed_doppler_index(doppler_bin, n_doppler) / (n_doppler * loop_period_s)


def tdm_phase_correction(doppler_hz: np.ndarray, slot_times_s: np.ndarray) -> np.ndarray:
    """(..., n_tx) complex128 factors exp(-j 2 pi f_d t_k) for Doppler frequencies (...) and
    slot times (n_tx,)."""
    f = np.asarray(doppler_hz, dtype=np.float64)[..., None]
    return np.exp(-2j * np.pi * f * np.asarray(slot_times_s, dtype=np.float64))


def compensate_tdm(x: np.ndarray, doppler_bin: np.ndarray, n_doppler: int, loop_period_s: float,
                   slot_times_s: np.ndarray, tx_of_element: np.ndarray | None = None) -> np.ndarray:
    """Remove the TDM slot phase of targets at ``doppler_bin`` (D,) from their channels.

    x : (D, n_tx, n_rx, L) channels by TX slot (firing order) and RX, or, with ``tx_of_element``
        (E,) giving each element's TX slot, (D, E, L) (e.g. the ULA's 86 elements)
    returns x times the correction, same shape (complex)
    raises CompensationError for arrays of the wrong shape or kind or with NaN/inf values, or
    a ``tx_of_element`` entry outside the ``n_tx`` slots
    """
    where = "compensate_tdm"
    x = checked_array(x, "x", CompensationError, where=where, kind="numeric", ndim=(3, 4),
                      axes="channels (D, n_tx, n_rx, L) or (D, elements, L)")
    doppler_bin = checked_array(doppler_bin, "doppler_bin", CompensationError, where=where,
                                kind="index", ndim=1, lengths={0: x.shape[0]},
                                axes=f"a Doppler bin per detection (D={x.shape[0]},)")
    slot_times_s = checked_array(slot_times_s, "slot_times_s", CompensationError, where=where,
                                 kind="real", ndim=1, axes="the TX slot times (n_tx,) in s")
    if not (np.isfinite(loop_period_s) and loop_period_s > 0) or int(n_doppler) < 1:
        raise CompensationError(f"{where}: loop_period_s must be a positive time and n_doppler a "
                                f"positive bin count; found {loop_period_s!r} and {n_doppler!r}")
    if tx_of_element is not None:
        tx_of_element = checked_array(tx_of_element, "tx_of_element", CompensationError,
                                      where=where, kind="index", ndim=1,
                                      axes="a TX slot per element (E,)")
        if tx_of_element.size and tx_of_element.max() >= slot_times_s.size:
            raise CompensationError(f"{where}: tx_of_element must name one of the "
                                    f"{slot_times_s.size} TX slots; found {tx_of_element.max()}")
    corr = tdm_phase_correction(doppler_frequency_hz(doppler_bin, n_doppler, loop_period_s),
                                slot_times_s)  # (D, n_tx)
    if tx_of_element is not None:
        if x.ndim != 3:
            raise CompensationError(f"{where}: x must be (D, elements, L) with tx_of_element; "
                                    f"found shape {x.shape}")
        return x * corr[:, np.asarray(tx_of_element)][:, :, None]
    if x.ndim != 4 or x.shape[1] != corr.shape[1]:
        raise CompensationError(f"{where}: x must be (D, n_tx={corr.shape[1]}, n_rx, L); found "
                                f"shape {x.shape}")
    return x * corr[:, :, None, None]


def compensate_tdm_velocity(x: np.ndarray, velocity_mps: np.ndarray, wavelength_m: float,
                            slot_times_s: np.ndarray, tx_of_element: np.ndarray) -> np.ndarray:
    """Remove the TDM slot phase using each detection's *unwrapped* radial velocity.

    On a moving car the Doppler bin gives the radial velocity only modulo ``2 v_max``; the slot
    phase ``2 pi f_d t_k`` with ``f_d = 2 v / lambda`` needs the true velocity (with the wrapped
    one the correction is off by ``2 pi m t_k / T_loop`` for m wraps, an error that grows with
    the TX slot and biases the angle). Choose the order first
    (:func:`blindspot.dsp.ego_motion.unwrap_doppler`), then compensate here.

    x : (D, E, L) snapshots on the elements, each element of TX slot ``tx_of_element`` (E,)
    velocity_mps : (D,) unwrapped radial velocity of each detection, m/s (+ = receding)
    wavelength_m : carrier wavelength, m; slot_times_s : (n_tx,) TX slot start times, s
    returns x times exp(-j 2 pi (2 v / lambda) t_k), same shape (complex)
    raises CompensationError for arrays of the wrong shape or kind or not finite, a wavelength
    that is not a positive number, or a ``tx_of_element`` entry outside the slots
    """
    where = "compensate_tdm_velocity"
    x = checked_array(x, "x", CompensationError, where=where, kind="numeric", ndim=3,
                      axes="snapshots (D, elements, L)")
    v = checked_array(velocity_mps, "velocity_mps", CompensationError, where=where, kind="real",
                      ndim=1, lengths={0: x.shape[0]},
                      axes=f"an unwrapped radial velocity per detection (D={x.shape[0]},)")
    slot_times_s = checked_array(slot_times_s, "slot_times_s", CompensationError, where=where,
                                 kind="real", ndim=1, axes="the TX slot times (n_tx,) in s")
    tx = checked_array(tx_of_element, "tx_of_element", CompensationError, where=where,
                       kind="index", ndim=1, lengths={0: x.shape[1]},
                       axes=f"a TX slot per element (E={x.shape[1]},)")
    if not (np.isfinite(wavelength_m) and wavelength_m > 0):
        raise CompensationError(f"{where}: wavelength_m must be a positive length; found "
                                f"{wavelength_m!r}")
    if tx.size and tx.max() >= slot_times_s.size:
        raise CompensationError(f"{where}: tx_of_element must name one of the "
                                f"{slot_times_s.size} TX slots; found {tx.max()}")
    corr = tdm_phase_correction(2.0 * v / wavelength_m, slot_times_s)     # (D, n_tx)
    return x * corr[:, tx][:, :, None]
