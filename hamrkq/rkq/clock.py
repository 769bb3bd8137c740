"""The kernel's clock: the compensated time ``t + t_lo`` of the tracks and
the steps that land it on doubles, so that each node reports the solution at
the time it names (docs/algorithm.md, "Limits").  Part of the compiled
kernel (:data:`hamrkq.backends.kernel.KERNEL_MODULES`); the conventions of
:mod:`hamrkq.rkq.loop`."""

from __future__ import annotations

from hamrkq.rkq import ddarith
from hamrkq.rkq.jit import jitable

__all__ = ["advance_time", "representable_step", "time_low_word", "time_sum"]


@jitable
def advance_time(state, h, clipped, target):
    """The compensated time ``t + t_lo`` moved by ``h`` (:func:`time_sum`);
    a clipped step's node is reported at its target, its state's time
    being the target plus the new low word."""
    t, t_lo = time_sum(state["t"], state["t_lo"], h)
    if clipped:
        t_lo += t - target  # an ulp at most: exact (Sterbenz)
        t = target
    state["t"] = t
    state["t_lo"] = t_lo


@jitable
def time_low_word(state, h):
    """The low word of the compensated time after a step of ``h``
    (:func:`advance_time`): zero where the step lands on a double."""
    return time_sum(state["t"], state["t_lo"], h)[1]


@jitable
def time_sum(t, t_lo, h):
    """``(t + t_lo) + h`` as a double and its low word, exact but for the
    rounding of the low word itself: TwoSum of ``t`` and ``h``, its error
    added to ``t_lo``, and renormalised.  (``t + (h + t_lo)``, as before,
    lost the rounding of ``h + t_lo``: a few 1e-18 over a run, which near a
    collision's ``dp/dt`` of 1e9 put the tracks 1e-8 off the exact solution
    at their reported times.)"""
    s, error = ddarith.two_sum(t, h)
    return ddarith.fast_two_sum(s, error + t_lo)


@jitable
def representable_step(t, t_lo, h):
    """A step as near ``h`` as an ulp of ``t`` that lands the compensated
    time ``t + t_lo`` on a double, ``fl(t + t_lo + h)``: every node's time is
    then exact (no low word), so a node reports the solution at the time it
    names.  With ``t + h`` rounded, the tracks arrive up to half an ulp of t
    away from the reported time: ``|f|`` x 2.3e-13 at t = 4000, a fifth of a
    tolerance of 1e-12 (docs/algorithm.md).  Exact whenever ``|h| <= |t|``
    (Sterbenz's lemma) and the low word is above an ulp of ``h``; the low
    word keeps what is left (:func:`hamrkq.rkq.certify.time_rounding`).  (``fl(t + h) - t``,
    as before, kept a low word left by the first steps, where ``h > t``,
    for the whole run: 7e-18 on the way to a collision, where ``dp/dt``
    reached 1e9, put the tracks 1e-8 off at their reported times.)"""
    t_new = t + (h + t_lo)
    return (t_new - t) - t_lo
