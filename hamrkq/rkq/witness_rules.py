"""The rounding witness's rules: when it runs, how its divergence is read,
and when it rounds its stage values stochastically.

The witness itself is :func:`hamrkq.rkq.steps.witness_step`; these are the
numbers the driver configures it with (docs/algorithm.md, "The rounding
witness").
"""

from __future__ import annotations

import math

import numpy as np

from hamrkq._tolerance import component_tolerance

__all__ = [
    "STAGE_ROUNDING_WEIGHTS",
    "WITNESS_BELOW",
    "WITNESS_REFERENCE_STEPS",
    "WITNESS_SAFETY",
    "component_scales",
    "needs_witness",
    "needs_witness_after_growth",
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


def component_scales(atol: np.ndarray, y0: np.ndarray) -> np.ndarray:
    """The size each component's rounding error is measured against: the
    largest ``|y0_j|`` of its half of the state (the coordinates or the
    momenta of a Hamiltonian state ``(q, p)``; the whole state when its
    length is odd), scaled by ``atol_i`` over the largest ``atol_j`` of the
    half, and at least ``|y0_i|``.

    With one ``atol`` for every component, each half is measured by its
    largest component.  Per-component floors declare the components'
    relative sizes: the outer solar system's file gives the momenta
    ``atol_i`` near ``m_i 1e-11``, from the Sun's 1e-11 to Pluto's 8e-20,
    because its momenta run from Jupiter's 5e-6 to Pluto's 2e-11.
    """
    size = np.abs(np.asarray(y0, dtype=np.float64))
    floor = np.broadcast_to(np.asarray(atol, dtype=np.float64), size.shape)
    d = size.shape[0]
    halves = (slice(0, d // 2), slice(d // 2, d)) if d % 2 == 0 else (slice(0, d),)
    scale = size.copy()
    for half in halves:
        top = size[half].max(initial=0.0) or size.max(initial=0.0) or 1.0
        largest = floor[half].max(initial=0.0)
        share = floor[half] / largest if largest > 0.0 else 1.0
        scale[half] = np.maximum(size[half], top * share)
    return scale


def needs_witness(
    atol: np.ndarray, rtol: np.ndarray, y0: np.ndarray, stage_rounding: bool = False
) -> bool:
    """Whether a run with the shadow estimate also runs the rounding witness.

    The quencher's rounding error, amplified along the orbit, reaches 1e-12
    to 1e-11 of the state's size over a few hundred periods (prentice2011
    over [0, 4000]: 5e-12 to 2.6e-11) and grows with the interval; the
    witness measures it, for one more quencher track, where some component's
    tolerance ``max(atol_i, rtol_i |y0_i|)`` is below :data:`WITNESS_BELOW`
    times its size (:func:`component_scales`).

    Measured against the largest ``|y0|`` of the whole state (25 AU), as
    before, Pluto's momentum (2e-11) asked for the witness on the outer
    solar system at every tolerance with the file's floors, which doubled
    the run's time for the same result (``benchmarks/witness_rule.txt``).
    On the rest of the catalogue, at ``atol`` 1e-4 to 1e-12 and ``rtol``
    1e-6 to 1e-10, both rules decide alike.

    A quencher whose weights magnify the rounding of its stage values
    (``stage_rounding``: DOP853's, :data:`STAGE_ROUNDING_WEIGHTS`) has a
    floor far above that: ``rk45q8`` on the FPU chain at ``rtol`` 1e-6
    (``atol`` 1e-9) ended 2e-9 from the truth where the shadow saw 2e-11,
    and returned a node of 1.74 delta; double-double stages took the
    quencher's error to 1e-11, the witness stopped the run in time
    (``benchmarks/promise_members.md``).  Such members run the witness at
    every tolerance.
    """
    if stage_rounding:
        return True
    tolerance = component_tolerance(atol, rtol, y0)
    return bool(np.any(tolerance < WITNESS_BELOW * component_scales(atol, y0)))


#: The steps of the runs :data:`WITNESS_BELOW` was measured on (prentice2011
#: over [0, 4000]: about 10 000 with ``auto``); rounding errors add like a
#: random walk, so a run of ``N`` steps gathers ``sqrt(N / 10 000)`` times as
#: much before the orbit amplifies it.
WITNESS_REFERENCE_STEPS = 10_000


def needs_witness_after_growth(
    atol: np.ndarray, rtol: np.ndarray, y0: np.ndarray, growth: float, steps: int
) -> bool:
    """Whether a run without the witness, whose estimate of Gamma grew
    ``growth``-fold over the second half of its ``steps`` steps (faster than
    a periodic orbit's ``t^2``, a factor 4), must run again with it.

    An error that grows like ``exp(lambda t)`` grows by ``g`` over the second
    half of a run and by ``g^2`` over all of it, the quencher's rounding
    alike; on a regular orbit by ``4`` and ``16``.  So the rounding can reach
    ``(g / 4)^2`` times what it reaches on a regular orbit of as many steps,
    and the witness runs where :func:`needs_witness`'s threshold, scaled by
    that and by ``sqrt(steps / WITNESS_REFERENCE_STEPS)``, is above some
    component's tolerance.  Measured (``benchmarks/witness_after_growth.md``,
    ``method="auto"`` on the catalogue at eight tolerances): made again every
    time, the witness run returned the same nodes on the Arenstorf orbit at
    1e-4 and 1e-6 (240- to 280-fold at its close approach, the quencher's
    true error a thousandth of the tolerance), the FPU chain at 1e-4 and
    1e-6 and the Pleiades at 1e-4, for 2.6 times the evaluations; at 1e-8 on
    the Arenstorf orbit it still runs.  A member whose quencher has no
    truncation error left (``rk45q12`` over three Arenstorf periods at 1e-8,
    66 500-fold) needs it: its true error was 42 times the tolerance
    (``benchmarks/error_growth.txt``).
    """
    ratio = max(1.0, growth / 4.0) ** 2 * math.sqrt(max(steps, 1) / WITNESS_REFERENCE_STEPS)
    tolerance = component_tolerance(atol, rtol, y0)
    return bool(np.any(tolerance < WITNESS_BELOW * ratio * component_scales(atol, y0)))
