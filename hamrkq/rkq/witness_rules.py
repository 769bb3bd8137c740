"""The rounding witness's rules: when it runs, how its divergence is read,
and when it rounds its stage values stochastically.

The witness itself is :func:`hamrkq.rkq.steps.witness_step`; these are the
numbers the driver configures it with (docs/algorithm.md, "The rounding
witness").
"""

from __future__ import annotations

import numpy as np

from hamrkq._tolerance import component_tolerance

__all__ = [
    "STAGE_ROUNDING_WEIGHTS",
    "WITNESS_BELOW",
    "WITNESS_SAFETY",
    "needs_witness",
    "tightest_tolerance",
]


def tightest_tolerance(atol: np.ndarray, rtol: np.ndarray, y: np.ndarray) -> float:
    """The smallest :func:`hamrkq._tolerance.component_tolerance` at the state ``y`` (infinite
    for no components): what ``method="auto"`` and the rounding witness are
    chosen by, at ``y0``."""
    return float(np.min(component_tolerance(atol, rtol, y), initial=np.inf))


#: The rounding witness's divergence from the quencher, times this, is taken
#: as the quencher's rounding error.  The divergence is one sample of a random
#: walk; the factor covers a sample below the quencher's own rounding
#: (measured: 0.57 of it on prentice2011 at 1e-12, ``docs/algorithm.md``).
WITNESS_SAFETY = 2.0

#: A quencher whose weights' absolute values sum to more than this has the
#: rounding witness round its stage values stochastically
#: (``hamrkq.rkq.arith.round_stochastically``): each stage value's rounding
#: reaches the step weighted by ``|b_j| |h J|``, which the witness, rounding
#: to nearest, shares with the quencher.  DOP853's weights sum to 12.9 and
#: let members return nodes of 1.17 and 1.29 delta on the Arenstorf orbit;
#: Cooper-Verner's sum to 1.0, Verner 9's to 1.8, Feagin's to 1.3 and 1.7,
#: where it is not needed and would cost about a quarter of a witness run's
#: time (the outer solar system at rtol 1e-6: 0.097 -> 0.122 s).
STAGE_ROUNDING_WEIGHTS = 4.0

#: With the shadow estimate, the witness runs where the tolerance is tighter
#: than this relative to the state's size (``needs_witness``).
WITNESS_BELOW = 3e-10


def needs_witness(atol: np.ndarray, rtol: np.ndarray, y0: np.ndarray) -> bool:
    """Whether a run with the shadow estimate also runs the rounding witness.

    The quencher's rounding error, amplified along the orbit, reaches 1e-12
    to 1e-11 of the state's size over a few hundred periods (prentice2011
    over [0, 4000]: 5e-12 to 2.6e-11) and grows with the interval; the
    witness measures it, for one more quencher track, where the
    tightest tolerance ``max(atol, rtol |y0|)`` is below :data:`WITNESS_BELOW`
    times the largest ``|y0|`` (or times 1 when ``y0`` is zero).
    """
    scale = float(np.max(np.abs(y0), initial=0.0)) or 1.0
    return tightest_tolerance(atol, rtol, y0) < WITNESS_BELOW * scale
