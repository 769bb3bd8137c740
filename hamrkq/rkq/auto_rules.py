"""``method="auto"``'s rules: its member by the tolerance and the system's dimension, its
quencher steps per step, and when a run is abandoned on its projection or
run again with more steps.

The kernel applies the projection (:func:`hamrkq.rkq.certify.projected_ratio`,
with the fractions and share below in its configuration);
:mod:`hamrkq.solve.auto` runs again with what these rules say.  The
measurements behind the numbers are in ``benchmarks/family.md`` and
``benchmarks/auto_member.md`` (docs/algorithm.md).
"""

from __future__ import annotations

import math
import operator

import numpy as np

from hamrkq.rkq.scales import small_state

__all__ = [
    "AUTO_FIRST_SUBSTEPS",
    "AUTO_LARGE_DIM",
    "AUTO_LARGE_MEMBER",
    "AUTO_LOOSE_TOLERANCE",
    "AUTO_MAX_SUBSTEPS",
    "AUTO_MEMBER",
    "AUTO_PROJECT_FROM",
    "AUTO_PROJECT_SHARE",
    "AUTO_PROJECT_UNTIL",
    "EXPONENTIAL_GROWTH",
    "SHADOW_SATURATION",
    "auto_abandon_substeps",
    "auto_member",
    "auto_member_per_row",
    "auto_retry_substeps",
    "auto_tolerance",
    "auto_tolerance_per_row",
    "error_growth",
    "growth_of_maxima",
    "growth_of_maxima_per_row",
    "middle_of",
    "shadow_departure",
]

#: ``method="auto"``: Verner's robust 8(7) pair with Feagin's 12th-order
#: quencher below :data:`AUTO_LARGE_DIM` state variables at tolerances
#: tighter than :data:`AUTO_LOOSE_TOLERANCE`, chosen by the measurements in
#: ``benchmarks/family.py`` (the fewest evaluations that reach the tolerance
#: with SUCCESS, every node within 1.05 of it, on prentice2011 and Kepler) ...
AUTO_MEMBER = "rk78q12"
#: ... and Verner's 7(6) pair with Verner's 9th-order quencher from
#: :data:`AUTO_LARGE_DIM` on: fewer evaluations on every large catalogue
#: problem at 1e-6 to 1e-9 when first measured (the outer solar system 11 to
#: 17 %, the Pleiades 6 to 65 %, the FPU chain 6 to 23 %); remeasured after
#: every exponential reading ran the witness (``benchmarks/auto_member.md``)
#: a tie, six cases each way (the Pleiades now cheaper with ``rk78q12`` at
#: every tolerance, the outer solar system with ``rk67q9``), 6.5 % fewer
#: summed over the twelve with ``rk67q9``, so the rule stands.  Small
#: systems are split: fewer on most short runs, but up to 53 % more on
#: prentice2011 (7 to 53 % at 1e-8 to 1e-10), whose 600 periods need the
#: 12th-order quencher, so they keep :data:`AUTO_MEMBER`.  What decides is
#: the number of periods, which auto cannot know before the run.
AUTO_LARGE_MEMBER = "rk67q9"
AUTO_LARGE_DIM = 12
#: ... and at tolerances of 1e-7 or looser (:func:`auto_tolerance`) for every
#: dimension: at atol 1e-4 to 1e-7 ``rk67q9`` needs fewer evaluations than
#: ``rk78q12`` in 40 of 44 cases (every small system, prentice2011 7 to 75 %
#: fewer, the Arenstorf orbit half; the Pleiades at 1e-5 to 1e-7 and the FPU
#: chain at 1e-6 take more, where ``rk67q9`` runs again with the witness;
#: ``benchmarks/auto_member_loose.md``).  Its
#: Verner-9 shadow also reads the quencher's error more closely on
#: prentice2011 at 1e-6 (Gamma over the true error 3.1, against 5.2 with
#: Feagin 12: ``benchmarks/family.md``).
AUTO_LOOSE_TOLERANCE = 1e-7
#: Quencher steps per step of ``method="auto"``'s first run.  Enough for a
#: few dozen orbits at any tolerance (Kepler e = 0.6 over 10 orbits at 1e-6:
#: the quencher's true error ends at 1.9e-9 with rk67q9 and 6.8e-9 with
#: rk78q12, 0.04 and 0.14 of the limit), and a run that
#: needs more learns it from its first 2 % (:func:`auto_abandon_substeps`) or
#: from where it stops (:func:`auto_retry_substeps`) and runs again.  The
#: pair's steps grow like tol^(1/8) and the quencher's error like h^12, so
#: the quencher's error relative to the tolerance grows like tol^(1/2) for
#: rk78q12: loose tolerances and long intervals need more steps (prentice2011
#: over [0, 4000] with rk78q12 in two steps a step stops at t = 530 at 1e-6
#: (rk67q9 at t = 1028) and t = 2693 at 1e-8).
AUTO_FIRST_SUBSTEPS = 2


def auto_member(dim: int, tolerance: float = 0.0) -> tuple[str, int]:
    """The member ``method="auto"`` runs for a system of ``dim`` state
    variables at the tolerance ``tolerance`` (:func:`auto_tolerance`), and
    its first run's quencher steps per step.  Both members start with
    :data:`AUTO_FIRST_SUBSTEPS` and estimate Gamma with the shadow track,
    but where the caller caps the steps (:meth:`SolveOptions.with_auto
    <hamrkq.options.SolveOptions.with_auto>`; ``tests/test_family.py``)."""
    name = AUTO_LARGE_MEMBER if _runs_the_large_member(dim, tolerance) else AUTO_MEMBER
    return name, AUTO_FIRST_SUBSTEPS


def auto_member_per_row(dim: int, tolerances: np.ndarray) -> np.ndarray:
    """The name of the member :func:`auto_member` runs at each of
    ``tolerances`` (an ensemble's members', :func:`auto_tolerance_per_row`),
    in whole-array operations; every member's first run takes
    :data:`AUTO_FIRST_SUBSTEPS`."""
    large = _runs_the_large_member(dim, np.asarray(tolerances, dtype=np.float64))
    return np.where(large, AUTO_LARGE_MEMBER, AUTO_MEMBER)


def _runs_the_large_member(dim: int, tolerance: float | np.ndarray) -> bool | np.ndarray:
    """Whether :func:`auto_member` is :data:`AUTO_LARGE_MEMBER`, elementwise
    where ``tolerance`` is an array."""
    return (dim >= AUTO_LARGE_DIM) | (tolerance >= AUTO_LOOSE_TOLERANCE)


def auto_tolerance(atol: np.ndarray, rtol: np.ndarray, y0: np.ndarray) -> float:
    """The tolerance :func:`auto_member` reads: the smallest component
    tolerance at ``y0``, ``min_k max(atol_k, rtol_k |y0_k|)``, over the
    state's size where that is above one (``max(1, max_k |y0_k|)``: a state
    in large units, astronomical units of 25 say, counts its tolerance
    relative to that size).  On a small state (:data:`~hamrkq.rkq.scales.SMALL_STATE`
    components) on Python floats, the whole-array rule's value
    (:func:`auto_tolerance_per_row`) bit for bit: every call of
    ``method="auto"`` asks it."""
    small = small_state(y0, atol, rtol)
    if small is None:
        return float(auto_tolerance_per_row(atol, rtol, y0))
    state, floor, relative = small
    sizes = list(map(abs, state))
    smallest = min(map(max, floor, map(operator.mul, relative, sizes)))
    return smallest / max(1.0, max(sizes))


def auto_tolerance_per_row(atol: np.ndarray, rtol: np.ndarray, states: np.ndarray) -> np.ndarray:
    """:func:`auto_tolerance` of each row of ``states`` (shape ``(m, d)``:
    an ensemble's ``y0``), in whole-array operations; of the one state
    where ``states`` is 1-D (a 0-d array then)."""
    sizes = np.abs(np.asarray(states, dtype=np.float64))
    delta = np.maximum(atol, rtol * sizes)
    # fmax: a size that is NaN counts as 1
    return delta.min(axis=-1) / np.fmax(1.0, sizes.max(axis=-1, initial=0.0))


#: The most quencher steps per step ``method="auto"`` tries.
AUTO_MAX_SUBSTEPS = 12


def auto_retry_substeps(
    substeps: int,
    z_order: int,
    gamma_ratio: float,
    gamma_limit: float,
    reached: float,
    growth: float | None = None,
) -> int | None:
    """Quencher steps per step for ``method="auto"``'s next run, or None.

    A run that stopped because the quencher's estimated error (not its
    rounding) reached ``gamma_limit`` of the tolerance, at the fraction
    ``reached`` of the interval, is run again with more quencher steps
    (:data:`AUTO_FIRST_SUBSTEPS` are enough for a few dozen orbits; a longer
    interval needs a more accurate quencher).  The
    quencher's error falls like ``m^-z``; on a periodic orbit its phase error
    grows like ``t^2``, so to reach the end with half the limit to spare the
    error must fall by ``r = 2 (gamma_ratio / gamma_limit) / reached^2`` and
    ``m`` grows to ``ceil(m r^(1/z))``, at least by one.  Where the estimate
    grew exponentially (``growth``-fold over the second half of the interval
    reached), it is projected to grow by that factor every half of that
    interval to the end, and a run that :data:`AUTO_MAX_SUBSTEPS` would not
    carry there gets None: more quencher steps only delay the stop of an
    unstable orbit.  A stop close to the end still runs again: the Arenstorf
    orbit at rtol 1e-6 stopped at 0.99998 of its period (its estimate grew
    770-fold through the close approach to the Moon) and reaches the end
    with one quencher step more.

    Parameters
    ----------
    substeps : int
        Quencher steps per step of the run that stopped.
    z_order : int
        Order of the quencher.
    gamma_ratio : float
        ``max |Gamma| / delta`` at the last node kept.
    gamma_limit : float
        The run's ``gamma_limit``.
    reached : float
        ``(t_last - t0) / (t_end - t0)``, in (0, 1).
    growth : float, optional
        The estimate's growth over the second half of the interval reached
        where it was exponential (above :data:`EXPONENTIAL_GROWTH`); None on
        a regular orbit.

    Returns
    -------
    int or None
        None when the stop was not the quencher's truncation error (its
        estimate is below half the limit: rounding stopped it, and more
        quencher steps do not help; or it is not finite), when
        ``AUTO_MAX_SUBSTEPS`` is reached, or, for an exponential growth,
        when it would not reach the end.
    """
    if not (0.0 < reached < 1.0) or not gamma_ratio >= 0.5 * gamma_limit:
        return None
    if math.isinf(gamma_ratio):
        # An estimate that stopped being finite measures no truncation error
        # that more quencher steps shrink (a diverged shadow track, whose
        # error does not depend on them, or a rounding variance whose square
        # overflowed): the oscillator at |y| = 5e169, atol 3e169, stopped at
        # t = 2.27 of 10, and auto raised OverflowError turning the infinite
        # ratio into quencher steps.  The run keeps its own status.
        return None
    if growth is None:
        return _grown_substeps(substeps, z_order, gamma_ratio / reached**2, gamma_limit)
    # in logarithms: a fast growth over a long remainder overflows a power
    halves_left = 2.0 * (1.0 - reached) / reached
    log_needed = math.log(2.0 * gamma_ratio / gamma_limit) + halves_left * math.log(growth)
    if math.log(substeps) + log_needed / z_order > math.log(AUTO_MAX_SUBSTEPS):
        return None
    projected = 0.5 * gamma_limit * math.exp(log_needed)  # _grown_substeps doubles it back
    return _grown_substeps(substeps, z_order, projected, gamma_limit)


def _grown_substeps(substeps: int, z_order: int, projected: float, gamma_limit: float):
    """``ceil(m r^(1/z))``, at least ``m + 1`` and at most
    :data:`AUTO_MAX_SUBSTEPS` (None at the most), for a quencher whose error
    at ``t_end`` is projected to be ``projected`` times the tolerance:
    ``r = 2 projected / gamma_limit`` leaves half the limit to spare."""
    if substeps >= AUTO_MAX_SUBSTEPS:
        return None
    needed = 2.0 * projected / gamma_limit
    if needed == math.inf:
        # a finite ratio over a tiny share of the interval squared: as many
        # as a large finite projection gets (the power of inf has no ceil)
        return AUTO_MAX_SUBSTEPS
    grown = math.ceil(substeps * needed ** (1.0 / z_order) - 1e-9)
    return min(AUTO_MAX_SUBSTEPS, max(substeps + 1, grown))


#: ``method="auto"``'s runs are projected to their end (and abandoned if they
#: would fail) from this fraction of the interval ...
AUTO_PROJECT_FROM = 0.02
#: ... to this one: later, a run goes on, and runs again only if it stops
#: (:func:`auto_retry_substeps`).
AUTO_PROJECT_UNTIL = 0.25
#: A run is abandoned when its projection exceeds this share of
#: ``gamma_limit``: the projection is rough, and a run that stops near its end
#: costs nearly twice (prentice2011 at 1e-8 with 401 output times: projected
#: just below the limit, it stopped at t = 3839 of 4000).
AUTO_PROJECT_SHARE = 0.5


def auto_abandon_substeps(
    substeps: int, z_order: int, projected: float, gamma_limit: float
) -> int | None:
    """Quencher steps per step for the run after ``method="auto"`` abandoned
    one on its projection; None if ``substeps`` is already the most.

    The quencher's truncation error grows like ``t^2`` on a periodic orbit
    (its phase error), so ``max |Gamma| / delta / reached^2`` at a node that
    covered the fraction ``reached`` of the interval projects it to ``t_end``
    (``hamrkq.rkq.certify.projected_ratio``).  A run whose projection exceeds
    :data:`AUTO_PROJECT_SHARE` of ``gamma_limit`` at a node between :data:`AUTO_PROJECT_FROM` and
    :data:`AUTO_PROJECT_UNTIL` of the interval is abandoned there and run
    again with the quencher steps :func:`auto_retry_substeps` would choose at
    its stop, without running to it: prentice2011 at 1e-6 with rk78q12 in 2
    steps a step stops at t = 530 of 4000, and is projected at 46 times the
    limit from t = 80.  On a chaotic orbit the error grows faster than the projection,
    and the run stops (and runs again) later; where it grows more slowly
    (the FPU chain, like t in its first 2 %), the next run may have more
    quencher steps than it needed.

    Parameters
    ----------
    substeps, z_order, gamma_limit
        As in :func:`auto_retry_substeps`.
    projected : float
        The projected ``max |Gamma| / delta`` at ``t_end``.
    """
    return _grown_substeps(substeps, z_order, projected, gamma_limit)


#: A run whose estimated error (its running largest ``|Gamma| / delta``) grew
#: by more than this factor over the second half of the interval it covered
#: grew faster than any power of ``t`` a regular orbit shows (``t^2``: a
#: factor 4), so exponentially: a chaotic orbit, or one near an unstable
#: equilibrium or a separatrix (:func:`error_growth`).  Measured on the runs
#: ``auto`` abandons or stops (``benchmarks/error_growth.txt``): 3.5 to 4.6 on
#: the catalogue's periodic orbits, 28 on prentice2011's first run at 1e-8
#: (abandoned after 2 % of its interval), 4500 on a Kepler orbit's first run
#: at rtol 1e-6 (its pericentre passages early in the run: one such run
#: alone is not enough, :mod:`hamrkq.solve.auto`); 147 to 1900 on a chaotic
#: Henon-Heiles orbit, 83 to 7500 on the Arenstorf orbit over several
#: periods, 295 on a Duffing separatrix (whose other runs, of fewer than 50
#: steps, were not measured then).  A run made again with the rounding witness
#: reads the same and is not a second reading.
EXPONENTIAL_GROWTH = 50.0


def middle_of(first: float, last: float) -> tuple[float, float]:
    """The middle of a run's interval from its first to its last kept node,
    and the direction of integration (1.0, or -1.0 backwards in time): a
    node at ``t`` is at or before the middle where
    ``(t - middle) * direction <= 0`` (:func:`error_growth`; the ensemble's
    batch loop folds its maxima with the same test)."""
    return first + 0.5 * (last - first), (1.0 if last >= first else -1.0)


def growth_of_maxima(to_middle: np.ndarray, to_end: np.ndarray, delta: np.ndarray) -> float:
    """:func:`error_growth` from each component's largest ``|Gamma_k|`` over
    the nodes up to the middle (``to_middle``) and over all of them
    (``to_end``), with the run's tolerance per component ``delta``: the
    largest ratio up to the middle of ``max_k |Gamma_k| / delta_k`` is
    ``max_k to_middle_k / delta_k``, the same bits (a division by a fixed
    ``delta_k`` keeps the order of its numerators)."""
    return float(growth_of_maxima_per_row(to_middle, to_end, delta))


def growth_of_maxima_per_row(
    to_middle: np.ndarray, to_end: np.ndarray, delta: np.ndarray
) -> np.ndarray:
    """:func:`growth_of_maxima` of each row of ``to_middle``, ``to_end`` and
    ``delta`` (shape ``(m, d)``, or ``delta`` one row for all: an
    ensemble's members), in whole-array operations; of the one run where
    they are 1-D (a 0-d array then)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        at_middle = np.max(np.asarray(to_middle) / delta, axis=-1)
        at_end = np.max(np.asarray(to_end) / delta, axis=-1)
    return np.asarray(_each_growth_of_ratios(at_middle, at_end), dtype=np.float64)


def _growth_of_ratios(at_middle: float, at_end: float) -> float:
    """The growth from the largest ratio of Gamma to the tolerance up to the
    middle and up to the end (:func:`growth_of_maxima`)."""
    if not (math.isfinite(at_middle) and math.isfinite(at_end)):
        return math.inf
    if at_middle <= 0.0:
        return math.inf if at_end > 0.0 else 1.0
    return at_end / at_middle


#: :func:`_growth_of_ratios` element by element: a run's two numbers decide
#: in Python, which numpy's ufuncs on two numbers would make four times as
#: slow (every solve asks), and an ensemble's members in one call.
_each_growth_of_ratios = np.frompyfunc(_growth_of_ratios, 2, 1)


def error_growth(t: np.ndarray, ratio: np.ndarray) -> float:
    """How much the quencher's estimated error grew over the second half of a run.

    Parameters
    ----------
    t : ndarray
        The run's node times, from its start (increasing, or decreasing on
        a run backwards in time).
    ratio : ndarray
        ``max_k |Gamma_k| / delta_k`` at the nodes.

    Returns
    -------
    float
        The running largest ratio at the last node over its value at the
        middle of the run's interval (``inf`` where that is zero, or where a
        ratio is not finite).  On a regular orbit the quencher's error grows
        like ``t`` or ``t^2`` (a factor 2 to 4); on an unstable one like
        ``exp(lambda t)``, and so does its rounding error, which the shadow
        estimate does not see.  Above :data:`EXPONENTIAL_GROWTH`, ``auto``
        measures the rounding (the witness) instead of adding quencher
        steps, which only push the stop a little later.
    """
    t = np.asarray(t, dtype=np.float64)
    ratio = np.asarray(ratio, dtype=np.float64)
    if t.size < 3:
        return 1.0
    middle, direction = middle_of(t[0], t[-1])
    before = (t - middle) * direction <= 0.0
    to_middle = ratio[before].max(initial=0.0, keepdims=True)
    return growth_of_maxima(to_middle, ratio.max(initial=0.0, keepdims=True), 1.0)


#: The shadow track (the quencher in one step a step, whose error is
#: ``m^z`` times the quencher's in ``m`` steps) may move at most this share of
#: the orbit's size away from the quencher: Gamma, their distance over
#: ``m^z - 1``, assumes both errors small and proportional; far from the
#: quencher the shadow saturates near the orbit's size and Gamma stops
#: growing with the quencher's error.  ``rk78q12`` with eight quencher steps
#: on a chaotic Henon-Heiles orbit at 1e-8 reached 2 and returned SUCCESS to
#: t = 1000, its nodes 40 times the tolerance from a certified run by
#: t = 177; on the catalogue, ``auto`` at 1e-4 to 1e-10 reaches at most 0.24
#: (prentice2011 at 1e-4).
SHADOW_SATURATION = 0.5


def shadow_departure(gamma: np.ndarray, scale: np.ndarray, amplification: float) -> np.ndarray:
    """Per node, the shadow track's distance from the quencher over the
    orbit's size: ``amplification max_k |Gamma_k| / scale_k`` with
    ``amplification = m^z - 1`` (``Member.shadow_scale``) and ``scale`` each
    component's size (:func:`hamrkq.rkq.scales.component_scales` of the
    run's largest ``|y|``).  The shadow's own error does not depend on the
    quencher steps ``m``: only a shorter step lowers it."""
    with np.errstate(invalid="ignore", divide="ignore"):
        return amplification * np.max(np.abs(gamma) / scale, axis=1)
