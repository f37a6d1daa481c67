"""Harmonics of one period of a signal sampled at uniform phase, and Ewoldt's elastic and viscous
stresses (Ewoldt, Hosoi and McKinley 2008, J. Rheol. 52, 1427): shared by the oscillation sweeps
and the program's ``oscillate`` steps."""

from __future__ import annotations

import numpy as np


def harmonics(samples, orders=(1, 3)) -> np.ndarray:
    """Complex harmonics c_n = (2/N) sum_k s_k exp(-i n 2 pi k/N) of one period sampled at
    uniform phase 2 pi k/N, k = 0..N-1 (last axis); returns shape (..., len(orders))."""
    s = np.asarray(samples, dtype=float)
    N = s.shape[-1]
    k = np.arange(N)
    E = np.exp(-1j * 2.0 * np.pi * np.outer(k, np.asarray(orders)) / N)
    return (2.0 / N) * (s @ E)


def elastic_viscous(stress) -> tuple[np.ndarray, np.ndarray]:
    """Ewoldt's elastic and viscous stresses of a strain-controlled cycle sampled at uniform
    phase from 0: sigma'(t) = (sigma(t) - sigma(-t))/2, sigma''(t) = (sigma(t) + sigma(-t))/2 [Pa]."""
    s = np.asarray(stress, dtype=float)
    mirror = s[(-np.arange(s.size)) % s.size]
    return 0.5 * (s - mirror), 0.5 * (s + mirror)


def cycle_harmonics(control: str, amplitude: float, stress, strain) -> tuple:
    """(c_sigma,1, c_gamma,1, (c_1, c_3) of the response) of one cycle of an oscillation of
    ``amplitude`` (strain gamma0 [-] or mixture stress sigma0 [Pa] as ``amplitude sin``, harmonic
    ``-i amplitude``), ``stress`` [Pa] its N samples at uniform phase from 0 and ``strain`` its
    N + 1 (the cycle's end too). The response is the stress under strain control, else the
    strain with its linear drift over the cycle removed; ``G* = c_sigma,1/c_gamma,1``."""
    if control == "strain":
        c = harmonics(stress)
        return c[0], -1j * amplitude, c
    n = len(stress)
    c = harmonics(np.asarray(strain[:n]) - (strain[n] - strain[0]) * np.arange(n) / n)
    return -1j * amplitude, c[0], c
