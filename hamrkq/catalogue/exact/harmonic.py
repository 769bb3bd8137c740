"""The harmonic oscillator's exact flow, a rotation of the phase plane."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from hamrkq.catalogue.exact._common import as_state, elapsed

__all__ = ["harmonic"]


def harmonic(
    t: object, y0: object, params: Mapping[str, float] | None = None, t0: float = 0.0
) -> np.ndarray:
    """Exact flow of ``H = (p**2 + q**2)/2``: a rotation of the phase plane.

    Parameters
    ----------
    t : float or array_like, shape (N,)
        Times.
    y0 : array_like, shape (2,)
        ``(q, p)`` at time ``t0``.
    params : mapping, optional
        Unused (the oscillator has unit frequency); accepted for a uniform
        signature.
    t0 : float, optional
        Time of ``y0``.

    Returns
    -------
    ndarray, shape (N, 2)
        ``q = q0 cos(t - t0) + p0 sin(t - t0)``, ``p = p0 cos(t - t0) - q0 sin(t - t0)``.
    """
    tau, tau_lo = elapsed(t, t0)
    q0, p0 = as_state(y0, 2, "harmonic")
    # cos and sin of tau + tau_lo to first order in tau_lo (below an ulp of
    # tau): t - t0 rounded to double lost eps |t - t0| / 2 of the phase,
    # 3.7e-11 at t = 1e6 from t0 = 1/3 (benchmarks/exact_accuracy.txt).
    c, s = np.cos(tau), np.sin(tau)
    c, s = c - s * tau_lo, s + c * tau_lo
    return np.column_stack([q0 * c + p0 * s, p0 * c - q0 * s])
