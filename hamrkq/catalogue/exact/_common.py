"""What the built-in exact solutions share: checks of their arguments, and
the phase of a periodic motion reduced without growing rounding."""

from __future__ import annotations

import mpmath
import numpy as np

from hamrkq.errors import InputError

__all__ = [
    "CONSTANT_DIGITS",
    "as_state",
    "as_times",
    "elapsed",
    "hi_lo",
    "reduced_phase",
    "two_prod",
    "two_sum",
]


def as_times(t: object) -> np.ndarray:
    """``t`` as a finite 1-D array of times."""
    arr = np.atleast_1d(np.asarray(t, dtype=float))
    if arr.ndim != 1:
        raise InputError(f"t must be a scalar or a 1-D array, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise InputError("t must be finite")
    return arr


def as_state(y0: object, dim: int, name: str) -> np.ndarray:
    """``y0`` as a finite state of length ``dim`` for the solution ``name``."""
    arr = np.asarray(y0, dtype=float)
    if arr.shape != (dim,):
        raise InputError(
            f"the {name!r} exact solution needs y0 of shape ({dim},) "
            f"(q's then p's), got shape {arr.shape}"
        )
    if not np.all(np.isfinite(arr)):
        raise InputError(f"y0 must be finite, got {arr.tolist()}")
    return arr


# -- the phase of a periodic motion, without growing rounding --------------------
#
# A flow evaluated as (a phase that grows like t) mod (a period) in doubles
# loses eps |t| of its phase: Kepler's mean anomaly n (t - t0) with n from a
# rounded energy was 1.8e-13 off after ten orbits at e = 0.6 (6.8e-12 at
# e = 0.9), a sixth of the tolerance a run at 1e-12 is measured against.
# The constants come from the double initial state in mpmath, and the phase
# is carried in double-double (Knuth's TwoSum, Dekker's product with
# Veltkamp's splitting; hamrkq.rkq.ddarith has the kernel's scalar forms),
# so the reduced phase is accurate to a few ulps for any t.

#: Digits of the constants computed in mpmath from the initial state.
CONSTANT_DIGITS = 34


def two_sum(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``s + e == a + b`` exactly (Knuth's TwoSum)."""
    s = a + b
    bb = s - a
    return s, (a - (s - bb)) + (b - bb)


def two_prod(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``p + e == a b`` exactly, for ``|a|, |b| <= 2**996``."""
    p = a * b

    def split(x):
        c = 134217729.0 * x  # 2**27 + 1
        hi = c - (c - x)
        return hi, x - hi

    a1, a2 = split(a)
    b1, b2 = split(b)
    return p, ((a1 * b1 - p) + a1 * b2 + a2 * b1) + a2 * b2


def hi_lo(value: mpmath.mpf) -> tuple[float, float]:
    """An mpmath number as a double-double ``(hi, lo)``."""
    hi = float(value)
    return hi, float(value - hi)


def reduced_phase(
    tau: np.ndarray, tau_lo: np.ndarray, rate: mpmath.mpf, start: mpmath.mpf, period: mpmath.mpf
) -> np.ndarray:
    """``start + rate (tau + tau_lo)`` reduced modulo ``period``, in
    ``[-period/2, period/2]``, accurate to a few ulps of ``period`` for any
    ``tau``."""
    rate_hi, rate_lo = hi_lo(rate)
    start_hi, start_lo = hi_lo(start)
    period_hi, period_lo = hi_lo(period)
    product, product_lo = two_prod(np.full_like(tau, rate_hi), tau)
    product_lo = product_lo + (rate_hi * tau_lo + rate_lo * tau)
    total, total_lo = two_sum(np.full_like(tau, start_hi), product)
    total_lo = total_lo + (start_lo + product_lo)
    turns = np.round(total / period_hi)
    off, off_lo = two_prod(turns, np.full_like(tau, period_hi))
    off_lo = off_lo + turns * period_lo
    phase, phase_lo = two_sum(total, -off)
    return phase + (phase_lo + (total_lo - off_lo))


def elapsed(t: object, t0: float) -> tuple[np.ndarray, np.ndarray]:
    """``t - t0`` as a double-double (exact)."""
    return two_sum(as_times(t), np.float64(-float(t0)))
