"""Roots and turning points of a function known at many points at once.

:func:`bracketed_roots` refines every bracket of a sign change together,
calling the function with all the active brackets' trial points in one
array (the events of a run: :mod:`hamrkq.events`); :func:`hermite_extreme`
is the turning value of the cubic through two points' values and slopes.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from hamrkq._floats import EPS

__all__ = ["ROOT_ITERATIONS", "bracketed_roots", "hermite_extreme"]


#: Iterations of :func:`bracketed_roots` before it gives up on a bracket
#: (bisection alone halves it 52 times to reach an ulp).
ROOT_ITERATIONS = 200


def bracketed_roots(
    function: Callable[[np.ndarray], np.ndarray],
    a: np.ndarray,
    b: np.ndarray,
    fa: np.ndarray,
    fb: np.ndarray,
) -> np.ndarray:
    """Roots of ``function`` in the brackets ``[a_k, b_k]`` (``fa_k`` and
    ``fb_k`` of opposite signs), all brackets at once, to 4 eps relative in
    ``t`` (brentq's finest).

    The Illinois variant of false position (Dowell & Jarratt 1971:
    superlinear, order 1.44), with a bisection wherever four steps did not
    halve a bracket; ``function`` is called with the active brackets' trial
    points together, so a run's every event costs about ten vectorised
    dense evaluations instead of ten Python-level calls per event
    (brentq, one root at a time: 1.6 ms an event, 7 times the integration
    itself over 95 000 events)."""
    a, b, fa, fb = (np.array(v, dtype=np.float64) for v in (a, b, fa, fb))
    root = b.copy()
    active = np.flatnonzero((fa != 0.0) & (fb != 0.0))
    root[fa == 0.0] = a[fa == 0.0]
    width = np.abs(b - a)
    before = np.full(a.size, np.inf)  # the width at the last check
    for iteration in range(ROOT_ITERATIONS):
        if active.size == 0:
            break
        aa, bb, ga, gb = a[active], b[active], fa[active], fb[active]
        with np.errstate(divide="ignore", invalid="ignore"):
            x = bb - gb * (bb - aa) / (gb - ga)
        # At least a tolerance from either end, as Brent steps: next to an
        # end whose value is already about zero, false position lands on
        # that end, and bisection would then creep up on it one halving at
        # a time (30 iterations where 4 do).
        tolerance = 2.0 * EPS * np.maximum(np.abs(aa), np.abs(bb))
        toward = np.sign(aa - bb)
        x = np.where(np.abs(x - bb) < tolerance, bb + toward * tolerance, x)
        x = np.where(np.abs(x - aa) < tolerance, aa - toward * tolerance, x)
        low, high = np.minimum(aa, bb), np.maximum(aa, bb)
        # Every fourth iteration: a bracket that did not halve in four is bisected.
        check = iteration % 4 == 0
        stalled = check & (width[active] > 0.5 * before[active])
        bisect = stalled | ~((x > low) & (x < high))
        x = np.where(bisect, 0.5 * (aa + bb), x)
        if check:
            before[active] = width[active]
        fx = function(x)
        root[active] = x
        # Keep the bracket: the new point replaces the end of its own sign;
        # where it replaces the same end twice running, the other end's
        # value is halved (Illinois), which keeps false position from
        # creeping up on the root from one side.
        flips = np.sign(fx) != np.sign(gb)
        a[active] = np.where(flips, bb, aa)
        fa[active] = np.where(flips, gb, np.where(bisect, ga, 0.5 * ga))
        b[active], fb[active] = x, fx
        width[active] = np.abs(b[active] - a[active])
        done = (fx == 0.0) | (
            width[active] <= 4.0 * EPS * np.maximum(np.abs(a[active]), np.abs(x))
        )
        done |= width[active] <= 1e-300
        active = active[~done]
    return root


def hermite_extreme(g0: float, g1: float, d0: float, d1: float) -> float:
    """The value at its turning point in (0, 1) of the cubic with values
    ``g0, g1`` and slopes ``d0, d1`` at 0 and 1 (slopes of opposite signs:
    there is one)."""
    a = 2.0 * (g0 - g1) + d0 + d1
    b = 3.0 * (g1 - g0) - 2.0 * d0 - d1
    # p'(s) = 3 a s^2 + 2 b s + d0 changes sign on (0, 1): its root there.
    roots = np.roots([3.0 * a, 2.0 * b, d0]) if a != 0.0 else np.array([-d0 / (2.0 * b)])
    real = roots.real[(np.abs(roots.imag) < 1e-12) & (roots.real > 0) & (roots.real < 1)]
    s = float(real[0]) if real.size else 0.5
    return ((a * s + b) * s + d0) * s + g0
