"""The rounding witness's rules: when it runs and how its divergence is read.

The witness itself is :func:`hamrkq.rkq.steps.witness_step`; these are the
numbers the driver configures it with (docs/algorithm.md, "The rounding
witness").
"""

from __future__ import annotations

import functools
import math
import operator

import numpy as np

from hamrkq._floats import EPS
from hamrkq._tolerance import component_tolerance
from hamrkq.rkq.scales import component_scales, scales_on_floats, scales_per_row, small_state

__all__ = [
    "CLOSE_APPROACH_RANGE",
    "EARLY_FRACTION",
    "FLOOR_STEPS",
    "REGULAR_GROWTH",
    "STAGE_ROUNDING_WEIGHTS",
    "STATE_GROWTH",
    "TIME_ROUNDING_MARGIN",
    "T_SQUARED_GROWTH",
    "WITNESS_BELOW",
    "WITNESS_REFERENCE_STEPS",
    "WITNESS_SAFETY",
    "WITNESS_SUBSTEPS",
    "WITNESS_SUBSTEPS_BELOW",
    "WITNESS_SUBSTEPS_NEAR_FLOOR",
    "amplification_factor",
    "beyond_length_factor",
    "close_approach_factor",
    "length_factor",
    "needs_witness",
    "needs_witness_after_run",
    "needs_witness_after_run_per_row",
    "needs_witness_per_row",
    "state_outgrew_its_start",
    "state_outgrew_its_start_per_row",
    "tightest_tolerance",
    "time_rounding_matters",
    "time_rounding_matters_per_row",
]


def tightest_tolerance(atol: np.ndarray, rtol: np.ndarray, y: np.ndarray) -> float:
    """The smallest :func:`hamrkq._tolerance.component_tolerance` at the state ``y`` (infinite
    for no components): what ``method="auto"`` and the rounding witness are
    chosen by, at ``y0``."""
    return float(np.min(component_tolerance(atol, rtol, y), initial=np.inf))


#: The rounding witness's divergence from the quencher, times this, is taken
#: as the quencher's rounding error.  The divergence is one sample of a random
#: walk; the factor covers a sample below the quencher's own rounding
#: (measured: 0.68 of it on prentice2011 at 1e-12, 0.93 on the harmonic
#: oscillator, ``benchmarks/algorithm_facts.txt``).
WITNESS_SAFETY = 2.0

#: A quencher whose weights' absolute values sum to more than this runs the
#: rounding witness at every tolerance (:func:`needs_witness`): each stage
#: value's rounding reaches the step weighted by ``|b_j| |h J|``, and
#: DOP853's weights, summing to 12.9, make that a floor far above other
#: quenchers' (members returned nodes of 1.17 and 1.29 delta on the Arenstorf
#: orbit before).  Cooper-Verner's sum to 1.0, Verner 9's to 1.8, Feagin's to
#: 1.3 and 1.7.  The witness rounds its stage values stochastically for
#: every quencher (:func:`hamrkq.rkq.steps.witness_step`): rounded to
#: nearest it shared them with the quencher, and at Kepler's pericentres,
#: where ``h J`` is large, missed Feagin 12's rounding thirtyfold
#: (``benchmarks/witness_rounding.md``).
STAGE_ROUNDING_WEIGHTS = 4.0

#: With the shadow estimate, the witness runs where the tolerance is tighter
#: than this relative to the state's size (``needs_witness``).
WITNESS_BELOW = 3e-10

#: With the shadow estimate, the witness runs where the quencher takes at
#: least this many steps per step of the pair (:func:`needs_witness`).  Each
#: step more shrinks the quencher's truncation error per step, which Gamma
#: sees, by ``(m / (m + 1))^z`` and leaves its rounding per step, which Gamma
#: does not see, as it was: from 2 to 5 steps, a factor 2.5^12 = 6e4 for
#: Feagin 12.  ``auto`` takes that many where the estimate grows fastest,
#: which is where the rounding is amplified most: a pendulum 1e-4 below its
#: separatrix (H = p^2/2 - 1.69 cos q, q0 = pi - 1e-4, to t = 300) at 1e-8
#: ran ``rk78q12`` with 7 quencher steps and returned SUCCESS with a node
#: 282 times the tolerance off, Gamma reading 1.1e-10 where the quencher was
#: 2.8e-6 off (its rounding: 0.988 of the tolerance with the quencher in
#: double-double); 6.9 to t = 100, 1.49 at 1e-3 below it, with 5 to 7 steps
#: (``benchmarks/separatrix_rounding.py``).  The catalogue's runs at
#: their tolerances take 2 to 4, the outer solar system 5 at rtol 1e-6,
#: where the witness runs already (``tests/test_family.py``).
WITNESS_SUBSTEPS = 5

#: With the shadow estimate, the witness also runs where the quencher takes
#: at least this many steps per step of the pair and some component's
#: tolerance is below :data:`WITNESS_SUBSTEPS_BELOW` times its size
#: (:func:`needs_witness`).  QA found (2026-11-27) the pendulum
#: ``H = p^2/2 - cos q`` from ``q0 = pi - 0.03`` over [0, 3000] at 5e-9
#: with four steps returning nodes 1.34 times the tolerance off;
#: ``benchmarks/separatrix_rounding.py`` (``H = p^2/2 - 1.69 cos q``) at
#: 2e-9: 2.11.  The catalogue's runs at four steps (prentice2011 and the FPU
#: chain at 1e-4 to 1e-7, ``benchmarks/auto_member_loose.md``) are above the
#: threshold (prentice2011 at 1e-7 by 1.3 times), where the quencher's
#: rounding, near 1e-11 of the state's size, cannot matter and the witness
#: would cost a second quencher.
WITNESS_SUBSTEPS_NEAR_FLOOR = 4

#: The tolerance, relative to the state's size, below which a quencher of
#: :data:`WITNESS_SUBSTEPS_NEAR_FLOOR` steps a step runs the witness: 19 times
#: above the QA case's (5e-9 of pi).
WITNESS_SUBSTEPS_BELOW = 3e-8


def needs_witness(
    atol: np.ndarray,
    rtol: np.ndarray,
    y0: np.ndarray,
    stage_rounding: bool = False,
    substeps: int = 1,
    time_scale: float = 0.0,
) -> bool:
    """Whether a run with the shadow or the tangent estimate also runs the
    rounding witness (the arguments besides the tolerances and the state:
    :func:`hamrkq.solve.dispatch.witness_rule_arguments`).

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
    every tolerance, and so does a quencher of ``substeps`` steps a step,
    :data:`WITNESS_SUBSTEPS` or more: its truncation error, which Gamma
    sees, has fallen below its rounding, which Gamma does not; with
    :data:`WITNESS_SUBSTEPS_NEAR_FLOOR` steps, where the tolerance is below
    :data:`WITNESS_SUBSTEPS_BELOW` of the size.  Where ``H``
    depends on the time, ``time_scale`` is the largest ``|t|`` of the run
    (zero otherwise): :func:`time_rounding_matters`.
    """
    if _witness_whatever_the_tolerance(stage_rounding, substeps):
        return True
    if time_rounding_matters(atol, rtol, y0, time_scale):
        return True
    # By content: a solve asks this of the same arrays several times (and
    # every solve asks: three conversions, not a generator over them)
    atol = np.asarray(atol, dtype=np.float64)
    rtol = np.asarray(rtol, dtype=np.float64)
    y0 = np.asarray(y0, dtype=np.float64)
    return _tolerance_below(
        _witness_threshold(substeps),
        atol.shape,
        atol.tobytes(),
        rtol.shape,
        rtol.tobytes(),
        y0.shape,
        y0.tobytes(),
    )


def needs_witness_per_row(
    atol: np.ndarray,
    rtol: np.ndarray,
    states: np.ndarray,
    *,
    time_scale: float = 0.0,
    stage_rounding: bool = False,
    substeps: int = 1,
) -> np.ndarray:
    """:func:`needs_witness` of each row of ``states`` (shape ``(m, d)``: an
    ensemble's ``y0``), in whole-array operations; the other arguments are
    the same for every row.

    Returns
    -------
    ndarray of bool, shape ``(m,)``
        The same decision as :func:`needs_witness` of that row alone.
    """
    states = np.asarray(states, dtype=np.float64)
    if _witness_whatever_the_tolerance(stage_rounding, substeps):
        return np.ones(states.shape[0], dtype=bool)
    atol, rtol = (np.asarray(a, dtype=np.float64) for a in (atol, rtol))
    below = _tolerances_below(_witness_threshold(substeps), atol, rtol, states)
    return time_rounding_matters_per_row(atol, rtol, states, time_scale) | below


def _witness_whatever_the_tolerance(stage_rounding: bool, substeps: int) -> bool:
    """Whether a run with the shadow or tangent estimate runs the witness at every
    tolerance (:func:`needs_witness`): its quencher's weights magnify its
    stages' rounding, or it takes :data:`WITNESS_SUBSTEPS` steps a step."""
    return stage_rounding or substeps >= WITNESS_SUBSTEPS


def _witness_threshold(substeps: int) -> float:
    """The tolerance, over the state's size, below which a quencher of
    ``substeps`` steps a step runs the witness (:func:`needs_witness`)."""
    if substeps >= WITNESS_SUBSTEPS_NEAR_FLOOR:
        return max(WITNESS_BELOW, WITNESS_SUBSTEPS_BELOW)
    return WITNESS_BELOW


@functools.lru_cache(maxsize=32)
def _tolerance_below(below, atol_shape, atol, rtol_shape, rtol, y0_shape, y0) -> bool:
    """:func:`_tolerances_below` of one state, on the arrays' bytes
    (hashable: memoised)."""
    atol, rtol, y0 = (
        np.frombuffer(data).reshape(shape)
        for shape, data in ((atol_shape, atol), (rtol_shape, rtol), (y0_shape, y0))
    )
    return bool(_tolerances_below(below, atol, rtol, y0.reshape(1, -1))[0])


def _tolerances_below(
    below: float, atol: np.ndarray, rtol: np.ndarray, states: np.ndarray
) -> np.ndarray:
    """Per row of ``states``, whether some component's tolerance is below
    ``below`` times its size (:func:`component_scales`)."""
    tolerance = component_tolerance(atol, rtol, states)
    return np.any(tolerance < below * component_scales(atol, states), axis=1)


#: Where ``H`` depends on the time, the witness runs when some component's
#: relative tolerance is below this many times the time's relative rounding,
#: ``eps max |t|`` (:func:`time_rounding_matters`).
TIME_ROUNDING_MARGIN = 1000.0


def time_rounding_matters(
    atol: np.ndarray, rtol: np.ndarray, y0: np.ndarray, time_scale: float
) -> bool:
    """Whether the rounding of the time, whose stage times ``t + c h`` are
    doubles (an ulp of 1.5e-8 at t = 1e8), could reach the tolerance of a
    run whose ``H`` depends on ``t`` and whose largest ``|t|`` is
    ``time_scale`` (0 for an autonomous ``H``): some component's tolerance
    is below :data:`TIME_ROUNDING_MARGIN` ``eps time_scale`` times its size.
    The quencher's stage times, and the double-double quencher's too, are
    rounded so, which Gamma does not see, nor the witness unless its own are
    rounded otherwise (stochastically: :func:`hamrkq.rkq.steps.witness_step`).  A driven
    oscillator ``H = p^2/2 + q^2/2 - 0.3 q cos(1.7 t)`` from t0 = 1e8 at
    1e-9 returned SUCCESS 11 times the tolerance off; from t0 = 2.45e6 at
    1e-10 and 1e-11, in double-double, 3.3 and 11 times; from t0 = 0 over
    300, at 1e-9 to 1e-12, within it.  Measured against 1e-3 of the
    tolerance over the state's size: from t0 = 0 over a few thousand time
    units at 1e-9 nothing runs the witness, from t0 = 1e4 at 1e-9 it runs."""
    # decided without arrays where H does not depend on t (every solve asks)
    return time_scale > 0.0 and bool(time_rounding_matters_per_row(atol, rtol, y0, time_scale))


def time_rounding_matters_per_row(
    atol: np.ndarray, rtol: np.ndarray, states: np.ndarray, time_scale: float
) -> np.ndarray:
    """:func:`time_rounding_matters` of each row of ``states`` (shape
    ``(m, d)``), in whole-array operations: a bool per row (of the one
    state where ``states`` is 1-D)."""
    states = np.asarray(states, dtype=np.float64)
    if time_scale <= 0.0:
        return np.zeros(states.shape[:-1], dtype=bool)
    atol, rtol = (np.asarray(a, dtype=np.float64) for a in (atol, rtol))
    tolerance = component_tolerance(atol, rtol, states)
    relative_rounding = EPS * time_scale * TIME_ROUNDING_MARGIN
    return np.any(tolerance < relative_rounding * component_scales(atol, states), axis=-1)


#: The steps of the runs :data:`WITNESS_BELOW` was measured on (prentice2011
#: over [0, 4000]: about 10 000 with ``auto``).
WITNESS_REFERENCE_STEPS = 10_000


#: The steps after which a regular orbit's quencher rounding, growing like
#: the square of the steps, is taken to reach :data:`WITNESS_BELOW` times
#: ``gamma_limit`` (0.05) of the state's size, 1.5e-11: prentice2011's
#: measured 1.2e-11 at 13 300 steps (``benchmarks/witness_length.txt``).
FLOOR_STEPS = 15_000


def length_factor(steps: int) -> float:
    """How much more rounding a regular run of ``steps`` steps gathers,
    amplified by the orbit, than :data:`WITNESS_BELOW` allows for.

    ``(N / FLOOR_STEPS)^2``: an error in the energy made by each step's
    rounding drifts the orbit's phase, by the number of steps times the time,
    and along a periodic orbit the rounding repeats from period to period.
    Measured (``benchmarks/witness_length.py``, ``witness_length.txt``): the
    quencher's true error in double on prentice2011 (``rk78q12``, four
    quencher steps a step) grows 3.6- to 5.2-fold each time the run doubles
    from 10 000 time units on (27 000 steps, 2.6e-11 of the state's size;
    426 000 steps, 9.1e-9), the double-double quencher's 8.6e-12 at the end;
    this law is 1.3 to 2 times above those points.  Kepler e = 0.6
    (``rk67q9``): 3.5- to 4.3-fold.  Never below ``sqrt(N / 10 000)``, a
    random walk's law, which the rule for an exponentially growing run was
    measured with before.
    """
    share = max(steps, 1)
    return max(math.sqrt(share / WITNESS_REFERENCE_STEPS), (share / FLOOR_STEPS) ** 2)


#: The ratio of a run's largest free step to its smallest above which its
#: quencher's rounding is taken to be amplified beyond the length's law
#: (:func:`close_approach_factor`).
CLOSE_APPROACH_RANGE = 2.0


def close_approach_factor(step_range: float) -> float:
    """How much more a run's quencher rounding is amplified than
    :func:`length_factor` allows for, when its free steps range over
    ``step_range`` (the largest over the smallest,
    :func:`hamrkq.rkq.loop.step_range`): ``max(1, step_range /``
    :data:`CLOSE_APPROACH_RANGE` ``)``.

    A close approach (a pericentre passage, an encounter) makes the steps
    short and the rounding of each step's energy large, and the orbit turns
    that into a drift of its phase.  Measured
    (``benchmarks/close_approach.py``, ``close_approach.txt``) on Kepler
    orbits with the witness off: the quencher's rounding over the length's
    law grows about like half the step range, from at most 0.45 of it at
    e = 0.3 (a range of 2.6) and 8.8 at e = 0.62 over 1000 periods (9.8) to
    3 100 at e = 0.99 (5 250); 22 of 36 runs returned SUCCESS with nodes
    1.06 to 1 740 times the tolerance off, from e = 0.59 at 4.2e-9 over 1000
    periods (a range of 8.6).  With this factor every node of the 36 is
    within 1.00 of it (most in double-double).  A range of 16, first chosen,
    missed QA's runs near e = 0.6 (1.06 to 1.09).  The catalogue's runs at
    their tolerances range 1.06 (the harmonic oscillator) to 8.8 (Kepler,
    e = 0.6, 10 periods: too short a run for the rule), and Arenstorf's and
    the Pleiades' above 500, which ran the witness already.
    """
    return max(1.0, step_range / CLOSE_APPROACH_RANGE)


#: The fraction of a run's interval from which the growth of its estimate to
#: the end is read for :func:`amplification_factor` (a checkpoint of the
#: kernel's, :func:`hamrkq.rkq.layout.checkpoint_fraction`).
EARLY_FRACTION = 1.0 / 16.0

#: The growth of a regular orbit's estimate from :data:`EARLY_FRACTION` of
#: its interval to the end by the length's law, ``t^2`` (:func:`length_factor`).
T_SQUARED_GROWTH = (1.0 / EARLY_FRACTION) ** 2

#: The growth from :data:`EARLY_FRACTION` above which it is read as the
#: orbit's amplification (:func:`amplification_factor`): ``t^2``'s, times
#: the scatter of regular orbits' readings above it.  Kepler's orbit at
#: e = 0.6 over ten periods at 1e-9 read 34 times ``t^2`` (its pericentre
#: passages: large truncation errors, not amplification), 4.1 times what
#: would run the witness again with ``t^2`` alone, and holds its tolerance
#: in double; the runs near the pendulum's separatrix that did not hold
#: read 9.2 to 1.3e6 times it (``benchmarks/amplification.py``,
#: ``benchmarks/amplification.txt``): 6 lies between.
REGULAR_GROWTH = 6.0 * T_SQUARED_GROWTH


def amplification_factor(growth: float) -> float:
    """How much more a run's quencher rounding is amplified than
    :func:`length_factor` allows for, when its estimate of Gamma grew
    ``growth``-fold from :data:`EARLY_FRACTION` of its interval to the end:
    ``max(1, growth /`` :data:`REGULAR_GROWTH` ``)``, and 1 where the growth
    is not finite (no reading that early: no evidence).  A noisy reading:
    a burst of the estimate at a first close encounter reads as
    amplification too, and runs again with the witness for nothing (about
    2.4 times that run's evaluations; docs/algorithm.md).

    The estimate sums the quencher's truncation errors, each carried by the
    orbit's flow, as the rounding is carried; a growth beyond a regular
    orbit's ``t^2`` is the flow amplifying them.  Near a pendulum's
    separatrix an error in the energy becomes a phase error ``1/(1 - E)``
    times larger, over the first approach to the unstable top: Gamma grew
    1.8e9-, 1.8e4- and 1.2e5-fold from 1/16 of the run (the second half
    reading 3.0, 5.4 and 2.3, regular), and named members returned nodes
    152, 9.4 and 1.5 times the tolerance off (``rk45q12`` at E = 1 - 1e-9,
    atol 1e-9; ``rk67q12`` and ``rk45q12`` at E = 1 - 1e-6, atol 1e-9 and
    atol = rtol = 1e-8; QA, session 18); with the quencher in double-double
    0.99, 1.00 and 1.00.  Its stages are the same on a close approach, which
    :func:`close_approach_factor` reads from the steps: the rule takes the
    larger of the two, not their product.
    """
    if not math.isfinite(growth):
        return 1.0
    return max(1.0, growth / REGULAR_GROWTH)


def beyond_length_factor(step_range: float, early_growth: float = 1.0) -> float:
    """How much more a run's quencher rounding is amplified than
    :func:`length_factor` allows for: the larger of
    :func:`close_approach_factor` of its step range and
    :func:`amplification_factor` of its estimate's growth from
    :data:`EARLY_FRACTION` of its interval to the end."""
    return max(close_approach_factor(step_range), amplification_factor(early_growth))


def needs_witness_after_run(
    atol: np.ndarray,
    rtol: np.ndarray,
    y0: np.ndarray,
    steps: int,
    size: np.ndarray | None = None,
    step_range: float = 1.0,
    early_growth: float = 1.0,
) -> bool:
    """Whether a run of ``steps`` steps without the witness, on a regular
    orbit, from ``y0``, whose components reached ``size`` (the largest
    ``|y_k|`` over the run, ``y0`` by default), must run again with it: its
    quencher's rounding, amplified by the orbit over the run's length and
    grown with the state, could reach the tolerance, which the shadow
    estimate does not see.  The rounding reaches :func:`length_factor` times
    what it reaches in :data:`WITNESS_REFERENCE_STEPS`, and
    :func:`beyond_length_factor` times that where the free steps ranged
    over ``step_range`` or the estimate grew ``early_growth``-fold from
    :data:`EARLY_FRACTION` of the interval to its end; the witness runs
    where :func:`needs_witness`'s threshold, scaled by both, is above some
    component's tolerance.

    The length alone: prentice2011 to t = 1e6 at atol 1e-8 with
    ``method="auto"`` (``rk78q12``, six quencher steps a step, no witness:
    1e-8 is above the threshold's 7.5e-10) returned nodes 2.2 times the
    tolerance off by t = 1.7e5, Gamma reading 3.5e-12, the quencher's true
    error 2.3e-8 (rounding: in double-double 1e-11).

    After an exponential growth of the estimate the witness runs whatever
    this says (:func:`hamrkq.solve.auto.witness_rerun_needed`).  This rule
    scaled the threshold by ``(g / 4)^2`` for a growth ``g`` over the second
    half of the run (``benchmarks/witness_after_growth.md``), which on the
    chaotic Henon-Heiles orbit (53-fold) put the rounding at 0.03 of the
    tolerance where it was 0.92.

    On a small state (:data:`~hamrkq.rkq.scales.SMALL_STATE` components) the rule is
    computed on Python floats, the values of the whole-array rule's
    (:func:`needs_witness_after_run_per_row`) bit for bit: every run with
    the shadow estimate asks it.
    """
    y0 = np.asarray(y0, dtype=np.float64)
    small = None
    if np.isscalar(steps) and np.isscalar(step_range) and np.isscalar(early_growth):
        small = small_state(y0, atol, rtol, y0 if size is None else size)
    if small is None:
        return bool(_after_run_rows(atol, rtol, y0, steps, size, step_range, early_growth))
    state, floor, relative, reached = small
    beyond = beyond_length_factor(step_range, early_growth)
    threshold = WITNESS_BELOW * (length_factor(steps) * beyond)
    # the rounding at the run's largest state (it grows with |y|)
    scales = scales_on_floats(floor, list(map(max, map(abs, state), reached)))
    # the tolerance at y0, as the rule at the start
    return any(
        max(a, q * abs(v)) < threshold * scale
        for a, q, v, scale in zip(floor, relative, state, scales, strict=True)
    )


def needs_witness_after_run_per_row(
    atol: np.ndarray,
    rtol: np.ndarray,
    states: np.ndarray,
    steps: int | np.ndarray,
    sizes: np.ndarray | None = None,
    step_range: float | np.ndarray = 1.0,
    early_growth: float | np.ndarray = 1.0,
) -> np.ndarray:
    """:func:`needs_witness_after_run` of each row of ``states`` (shape
    ``(m, d)``: an ensemble's ``y0``), with its row of ``sizes`` and its
    element of ``steps``, ``step_range`` and ``early_growth`` (or one value
    for every row), in whole-array operations: a bool per row (of the one
    state where ``states`` is 1-D, and the others numbers)."""
    states = np.asarray(states, dtype=np.float64)
    numbers = np.isscalar(steps) and np.isscalar(step_range) and np.isscalar(early_growth)
    if states.ndim == 1 and numbers:
        return np.bool_(
            needs_witness_after_run(atol, rtol, states, steps, sizes, step_range, early_growth)
        )
    return _after_run_rows(atol, rtol, states, steps, sizes, step_range, early_growth)


def _after_run_rows(atol, rtol, states, steps, sizes, step_range, early_growth=1.0) -> np.ndarray:
    """:func:`needs_witness_after_run_per_row` in whole-array operations."""
    states = np.asarray(states, dtype=np.float64)
    if np.isscalar(steps) and np.isscalar(step_range) and np.isscalar(early_growth):
        ratio = length_factor(steps) * beyond_length_factor(step_range, early_growth)
    else:  # one ratio per row, along the components
        ratio = _each_length_factor(steps) * _each_beyond_length_factor(step_range, early_growth)
        ratio = np.asarray(ratio, dtype=np.float64)[..., None]
    # The tolerance at y0, as the rule at the start (with rtol, a component
    # that is 0 there has atol, as it has wherever it crosses zero); the
    # rounding at the run's largest state (it grows with |y|).
    tolerance = component_tolerance(atol, rtol, states)
    largest = np.maximum(np.abs(states), states if sizes is None else sizes)
    threshold = WITNESS_BELOW * ratio * component_scales(atol, largest)
    return (tolerance < threshold).any(axis=-1)


#: :func:`length_factor` and :func:`close_approach_factor` element by
#: element (an ensemble's members): the rules in Python on numbers, which
#: numpy's ufuncs on one number would make several times as slow (every
#: solve asks).
_each_length_factor = np.frompyfunc(length_factor, 1, 1)
_each_beyond_length_factor = np.frompyfunc(beyond_length_factor, 2, 1)


#: How many times its start's size (:func:`component_scales`) a run of the
#: tangent estimate (``rk34q8``'s) must outgrow before its rounding is checked
#: with the witness (:func:`state_outgrew_its_start`): the outer solar
#: system's grow 2.8-fold at atol 1e-8 (its largest position from 25.7 to
#: 47.1 AU), the pendulum going over the top from q = 0 to q = 13 000.
STATE_GROWTH = 10.0


def state_outgrew_its_start(
    atol: np.ndarray, rtol: np.ndarray, y0: np.ndarray, size: np.ndarray
) -> bool:
    """Whether a run from ``y0`` whose components reached ``size`` (the
    largest ``|y_k|``) grew more than :data:`STATE_GROWTH`-fold, so that this
    growth alone calls for the witness (the rule at the start, at ``size``
    and not at ``y0``): the one rule after a run for the tangent estimate.

    The paper's runs are not made again after an exponential growth, for
    their length (its short steps gather less rounding than the law in
    steps says: ``benchmarks/promise_members.md``) or for their rounding at
    the state they start from (rk34q8's documented limit,
    docs/algorithm.md).  The pendulum going over the top from q = 0, p = 3 at
    1e-9 returned nodes 1.11 times the tolerance off before it stopped at
    t = 800 (q = 2080): its quencher's rounding grows with ``|q|``, and the
    tangent Gamma does not see rounding.

    On a small state (:data:`~hamrkq.rkq.scales.SMALL_STATE` components) the rule is computed
    on Python floats, the values of the whole-array rule's
    (:func:`state_outgrew_its_start_per_row`) bit for bit: every run of the
    tangent estimate asks it (18 us of a tiny problem's call on arrays).
    """
    y0 = np.asarray(y0, dtype=np.float64)
    small = small_state(y0, atol, size)
    if small is not None:
        state, floor, reached = small
        start = list(map(abs, state))
        before = scales_on_floats(floor, start)
        after = scales_on_floats(floor, list(map(max, start, reached)))
        if 0.0 not in before:  # (a quotient by zero is NumPy's: inf or NaN)
            grew = max(map(operator.truediv, after, before))
            if not grew > STATE_GROWTH:
                return False  # the common case, decided without the rules
            steps = WITNESS_REFERENCE_STEPS
            return needs_witness_after_run(
                atol, rtol, y0, steps, size
            ) and not needs_witness_after_run(atol, rtol, y0, steps)
    size = np.asarray(size, dtype=np.float64)
    return bool(state_outgrew_its_start_per_row(atol, rtol, y0[None], size[None])[0])


def state_outgrew_its_start_per_row(
    atol: np.ndarray, rtol: np.ndarray, states: np.ndarray, sizes: np.ndarray
) -> np.ndarray:
    """:func:`state_outgrew_its_start` of each row of ``states`` (shape
    ``(m, d)``: an ensemble's ``y0``) with its row of ``sizes``, in
    whole-array operations: a bool per row (of the one state where
    ``states`` is 1-D)."""
    states = np.asarray(states, dtype=np.float64)
    sizes = np.asarray(sizes, dtype=np.float64)
    if states.ndim == 1:
        return np.bool_(state_outgrew_its_start(atol, rtol, states, sizes))
    m = states.shape[0]
    # the scales at the start and at the run's largest state, in one pass
    both = np.empty((2 * m, states.shape[1]))
    np.abs(states, out=both[:m])
    np.maximum(both[:m], sizes, out=both[m:])
    scales = scales_per_row(np.asarray(atol, dtype=np.float64), both)
    grew = np.max(scales[m:] / scales[:m], axis=1)
    # the common case, decided without the rules (every call pays); NaN did not grow
    outgrew = grew > STATE_GROWTH
    if not outgrew.any():
        return outgrew
    rows = np.flatnonzero(outgrew)
    steps = WITNESS_REFERENCE_STEPS
    at_size = needs_witness_after_run_per_row(atol, rtol, states[rows], steps, sizes[rows])
    at_start = needs_witness_after_run_per_row(atol, rtol, states[rows], steps)
    outgrew[rows] = at_size & ~at_start
    return outgrew
