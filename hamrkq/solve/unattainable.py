"""Why a run stopped with ``TOLERANCE_UNATTAINABLE``, and the remedy that
works (:func:`unattainable`): the quencher's floor in double (measured by
the rounding witness), its truncation error, an exponential-looking growth
of the estimate (or the state's own growth), a shadow that saturated, an
estimate that stopped being finite, a component passing close to zero, an
event state the tolerance cannot vouch for.  :mod:`hamrkq.solve.messages`
makes the message of every status and calls it for this one.
"""

from __future__ import annotations

import math
import sys

import numpy as np

from hamrkq._floats import EPS
from hamrkq._tolerance import component_tolerance
from hamrkq.rkq.auto_rules import EXPONENTIAL_GROWTH, SHADOW_SATURATION
from hamrkq.rkq.driver import RunOutput
from hamrkq.rkq.family import MEMBERS
from hamrkq.solve.auto import (
    double_double_can_help,
    tangent_follows_saturation,
)
from hamrkq.solve.dispatch import (
    Task,
    member_of,
    time_rounding_limits,
    time_scale,
)
from hamrkq.solve.event_check import stored_rounding_limits
from hamrkq.solve.growth import growth, one_step_jump
from hamrkq.solve.output_times import (
    atol_above_output_rounding,
    output_rounding,
    output_rounding_limits,
)
from hamrkq.solve.shadow import largest_state
from hamrkq.solve.truncation_remedies import growth_text, remedies, size_growth

__all__ = ["NEAR_OVERFLOW", "equation_of", "state_size", "unattainable"]


def equation_of(task: Task, index: int) -> str:
    """Which derivative a state component's right-hand side is, in words."""
    ham = task.ham
    n = ham.n
    if index < 0:
        return "the right-hand side"
    if index < n:
        return f"d{ham.q[index]}/dt = dH/d{ham.p[index]}"
    return f"d{ham.p[index - n]}/dt = -dH/d{ham.q[index - n]}"


def _where_it_failed(out: RunOutput, task: Task) -> tuple[str, bool]:
    """The first sentences for an unattainable tolerance: where and by how
    much; and whether they are the whole message (the value's own rounding
    at an event state or an output time, where one remedy works)."""
    o = task.options
    if out.event_failure is not None:
        text = _event_failed(out, task)
        if stored_rounding_limits(out.event_failure, o.gamma_limit):
            return text + (
                f" Of that, {out.event_failure.stored_ratio:.3g} x the tolerance is the value's "
                "own rounding: it is stepped in double from the node stored in double before "
                "it, whose last bit is an ulp of the state's size there, not of the component "
                "near zero; more quencher steps or the quencher in double-double do not go "
                "below it. A larger atol is what works."
            ), True
        return text, False
    text = (
        f"At t = {float(out.t_last)!r} the quencher's estimated global error plus its rounding "
        f"would reach {out.max_ratio:.3g} x the tolerance (gamma_limit = {o.gamma_limit:g}), "
        "so the tolerance can no longer be certified; the run ends at the last node where it "
        "held."
    )
    if output_rounding_limits(out, task):
        return text + (
            " That is an output time of t_eval inside a step, whose value is stepped with "
            "the quencher's stages in double: its own rounding, an ulp of the state's "
            f"size there, is {output_rounding(out, task):.3g} x the tolerance, and where a "
            "component passes zero under rtol its tolerance is atol alone. More quencher "
            "steps or the "
            "quencher in double-double do not go below it; a larger atol (at least "
            f"{atol_above_output_rounding(out, task):.2g}) "
            "is what works."
        ), True
    return text, False


def _double_double_remedy(under_cap: bool) -> str:
    """The quencher in double-double as what works at the floor: auto
    switches to it by itself, except where a caller's ``max_step`` made the
    tangent estimate the default (``under_cap``,
    :func:`hamrkq.solve.auto.double_double_can_help`), which naming it
    replaces by the shadow."""
    why = (
        "with the shadow estimate of Gamma, its only one there, in place of the tangent one "
        "that max_step selects"
        if under_cap
        else "method='auto' switches to it by itself unless quencher_precision='double' is given"
    )
    return (
        " What works: quencher_precision='double-double' (the quencher's stages and f in "
        f"double-double, 5 to 7 times the cost per evaluation; {why}), a looser tolerance "
        "or a shorter interval."
    )


def _truncation_too(out: RunOutput, task: Task) -> str:
    """A sentence where a stop at the floor would stop below it too: the
    estimate less the rounding, the quencher's truncation error, is above
    the limit by itself (QA: ``rk56q9`` on Kepler at e = 0.7, rtol 1e-8,
    atol 1e-14, 26.4 x the tolerance of which 21.9 rounding, stopped at the
    same t in double-double, where its message had named double-double as
    what works)."""
    truncation = out.max_ratio - out.floor_ratio
    if not truncation > task.options.gamma_limit:
        return ""
    return (
        f" The rest, {truncation:.3g} x the tolerance, is the quencher's truncation error, "
        "above the limit by itself: below the floor the run stops there too unless the "
        "quencher takes more steps (z_substeps) or the tolerance is looser."
    )


def unattainable(out: RunOutput, task: Task) -> str:
    if out.saturated:
        return _shadow_saturated(out, task)
    if not math.isfinite(out.max_ratio):
        return _estimate_diverged(out, task)
    text, final = _where_it_failed(out, task)
    if final:
        return text
    at_state, final = _at_the_last_state(out, task)
    text += at_state
    if final:
        return text
    if out.at_rounding_floor:
        text += (
            f" The quencher's own rounding error, measured by the rounding witness (the "
            f"quencher run again with its sums in the opposite order), is "
            f"{out.floor_ratio:.3g} x the tolerance: "
        )
        member = member_of(task)
        if member.stage_rounding_dominates:
            pair = task.options.method.split("q")[0]
            quiet = [
                name
                for name, other in MEMBERS.items()
                if name.startswith(pair + "q") and not other.stage_rounding_dominates
            ]
            weights = float(np.abs(member.quencher.b).sum())
            # "may": where the floor is double precision's, not this
            # quencher's, they stop about as soon (QA: rk34q8 on Kepler at
            # e = 0.9, atol 1e-12 at t = 6.13, rk34q9/q10/q12 at 6.23-6.25)
            text += (
                "this quencher's floor for this orbit and interval (its weights, whose "
                f"absolute values sum to {weights:.3g}, magnify the rounding of its stages) "
                "or double precision's; the same pair with another quencher "
                f"({', '.join(map(repr, quiet))}) goes below the first, not the second."
            )
        else:
            # Not "no member or step size in double goes below it": rk34q12
            # in double reached t = 578 on prentice2011 at 1e-12 where auto's
            # run in double stopped at 80 (QA found 499 and 129 before the
            # witness rounded every quencher's stage values stochastically).
            text += "this is double precision's floor for this orbit and interval."
        text += _time_floor_note(task) + _truncation_too(out, task)
        if double_double_can_help(task, under_cap=True) and not double_double_can_help(task):
            return text + _double_double_remedy(under_cap=True)
        if not double_double_can_help(task):
            if member.stage_rounding_dominates:
                # rk34q8 (the tangent estimate): no double-double quencher,
                # but another member, or auto, goes below this floor
                return text + (
                    " What works: method='auto' (which chooses a member and runs its "
                    "quencher in double-double where needed), a looser tolerance or a "
                    "shorter interval; one of those members may."
                )
            return text + " A looser tolerance or a shorter interval is what works."
        return text + _double_double_remedy(under_cap=False)
    factor = growth(out, task)
    # the state's growth matters only after an exponential-looking reading
    grown = size_growth(out, task) if factor > EXPONENTIAL_GROWTH else None
    if factor > EXPONENTIAL_GROWTH:
        text += growth_text(out, task, factor, grown)
    steps = out.stats.get("steps", 0)
    rounded = out.stats.get("roundoff_steps", 0)
    if steps and 2 * rounded > steps:
        text += " The quencher's error has reached double precision's rounding floor here"
        if double_double_can_help(task, under_cap=True):
            return text + "." + _double_double_remedy(under_cap=True)
        return text + (
            ": a looser tolerance, or a shorter interval (the horizon of double precision for "
            "this orbit), is what works."
        )
    return text + " What helps: " + "; ".join(remedies(out, task, factor, grown)) + "."


def _at_the_last_state(out: RunOutput, task: Task) -> tuple[str, bool]:
    """What the last node's state says about a stop: the stored values'
    own rounding at the limit (final), one step that carried the estimate
    from the node far past the limit (final, :func:`one_step_jump`), or a
    component passing zero under ``rtol`` (:func:`_near_zero`)."""
    if not out.y.size:
        return "", False
    y = np.abs(out.y[-1])
    floor = float(np.max(EPS * y / component_tolerance(task.atol, task.rtol, y)))
    if floor >= 0.5 * task.options.gamma_limit:
        return (
            f" The tolerance is at double precision's floor for this state (the rounding "
            f"of the stored values alone is {floor:.3g} x the tolerance): loosen atol/rtol."
        ), True
    if out.event_failure is not None:
        return "", False
    near_zero = _near_zero(out, task)
    before = None if near_zero or out.at_rounding_floor else one_step_jump(out, task)
    if before is None:
        return near_zero, False
    longest = float(np.max(np.abs(np.diff(out.t))))
    # Rejecting such a step and trying it shorter let later steps pass a
    # pulse with no stage in it, silently (tried and reverted, 4b784eb).
    return (
        f" One step from that node carried the estimate from {before:.3g} to "
        f"{out.max_ratio:.3g} x the tolerance: its stages met what the steps before them did "
        "not, a feature of f narrower than the steps (a pulse in time, a close encounter) or "
        "a stretch the steps grew too long for, and longer steps can pass such a feature with "
        "no stage in it, unseen. A max_step below that feature's width is what works (the "
        f"longest step kept was {longest:.3g})."
    ), True


#: A component whose tolerance at the last node is below this fraction of its
#: largest along the run is passing close to zero (with ``rtol``).
NEAR_ZERO = 0.1


def _near_zero(out: RunOutput, task: Task) -> str:
    """A sentence for a stop where ``rtol`` shrank the tolerance of the
    component closest to its limit because that component passes close to
    zero (its tolerance is then ``atol`` alone), or "".

    With a tiny ``atol`` (1e-20, say) nothing is certified there, and the
    first remedy is an ``atol`` the size of the error one accepts near zero
    (Kepler at rtol 1e-8, atol 1e-20 with rk34q8 stopped as q1 crossed zero
    at t = 68.7, and the message named only other members)."""
    if out.gamma is None or not np.any(task.rtol > 0) or out.y.shape[0] < 2:
        return ""
    delta = component_tolerance(task.atol, task.rtol, out.y)
    last = delta[-1]
    k = int(np.argmax(np.abs(out.gamma[-1]) / last))
    typical = float(np.max(delta[:, k]))
    if task.rtol[k] <= 0 or last[k] >= NEAR_ZERO * typical:
        return _crossing_zero(out, task, delta)
    name = task.ham.names[k]
    return (
        f" The component closest to its limit, {name} = {out.y[-1, k]:.3g}, is passing "
        f"close to zero: its tolerance max(atol, rtol |{name}|) is {last[k]:.3g} there, "
        f"{last[k] / typical:.2g} of its largest along the run ({typical:.3g}), and it "
        f"falls to atol = {task.atol[k]:.3g} at zero, so there the limit is atol's: a "
        "larger atol (the error acceptable where a component is near zero) helps too."
    )


#: An ``atol`` below this fraction of a component's largest tolerance is too
#: small to certify anything where the component passes zero.
TINY_ATOL = 1e-3


def _crossing_zero(out: RunOutput, task: Task, delta: np.ndarray) -> str:
    """The sentence of :func:`_near_zero` where the last node is not near a
    zero, but a component that crosses zero along the run has an ``atol``
    too small to certify anything there: the step that stopped the run ends
    near such a crossing.  The oscillator at rtol 1e-6, atol 1e-30 stopped
    with ``auto`` at t = 30.68, the next node near p = 0, and its message
    named only more quencher steps, other members and double-double (QA)."""
    crossing = [
        k
        for k in range(out.y.shape[1])
        if task.rtol[k] > 0
        and task.atol[k] < TINY_ATOL * float(np.max(delta[:, k]))
        and np.any(np.diff(np.signbit(out.y[:, k])))
    ]
    if not crossing:
        return ""
    names = ", ".join(task.ham.names[k] for k in crossing)
    atol = float(min(task.atol[k] for k in crossing))
    return (
        f" {names} {'crosses' if len(crossing) == 1 else 'cross'} zero along the run, where "
        f"max(atol, rtol |y|) falls to atol ({atol:.3g}): a step that ends near such a "
        "crossing certifies nothing above atol. A larger atol (the error acceptable where a "
        "component is near zero) is the first remedy."
    )


def _event_failed(out: RunOutput, task: Task) -> str:
    """The first sentences for a run ended before an event state where its
    promise failed (:mod:`hamrkq.solve.event_check`)."""
    failure = out.event_failure
    k = failure.component
    name = task.ham.names[k]
    text = (
        f"At the state of event {failure.label!r} at t = {failure.t!r} the quencher's "
        f"estimated global error and rounding (Gamma between the nodes around it, and the "
        f"rounding of the value) would reach "
        f"{failure.ratio:.3g} x the tolerance there (gamma_limit = "
        f"{task.options.gamma_limit:g}), so that state cannot be certified; the run ends at "
        "the last node before it."
    )
    delta = component_tolerance(task.atol, task.rtol, failure.state)[k]
    if task.rtol[k] > 0 and delta <= task.atol[k]:
        text += (
            f" There {name} = {failure.state[k]:.3g}: it passes zero at the event, where its "
            f"tolerance max(atol, rtol |{name}|) is atol = {task.atol[k]:.3g}, far below "
            f"the nodes' on either side; a larger atol (the error acceptable where {name} is "
            "near zero) helps too."
        )
    return text


def _shadow_saturated(out: RunOutput, task: Task) -> str:
    """The message for a run ended where its shadow track left the linear
    regime (:func:`hamrkq.solve.shadow.within_linear_shadow`)."""
    member = member_of(task)
    # With no node kept, the first output time was beyond already.
    when = f"After t = {float(out.t_last)!r}" if out.t.shape[0] else "By the first output time"
    text = (
        f"{when} the shadow track behind the estimate of the "
        f"quencher's global error (Gamma: the quencher in one step a step, whose error is "
        f"{member.z_substeps}^{member.z_order} times the quencher's) had moved "
        f"{out.saturated:.3g} of the orbit's size away from the quencher, more than "
        f"{SHADOW_SATURATION:g}: it no longer grows with the quencher's error (it "
        "saturates), so Gamma can no longer certify the tolerance; the run ends at the last "
        "node where it held."
    )
    grew = growth(out, task) > EXPONENTIAL_GROWTH
    # A tighter tolerance, not a looser one: the shadow's error is m^z times
    # the quencher's, which falls with the pair's steps, and saturation does
    # not depend on the tolerance.  A looser one was named, and it only
    # lengthens the steps: the pendulum near its separatrix (E = 1 - 1e-9,
    # three periods) stopped with auto at 1e-6, 1e-7 and 1e-8 and reached the
    # end at 1e-9 and 1e-10 (found by QA).  (After the growth's sentence,
    # which names them, the two remedies are not named again.)
    tighter_tolerance = (
        "a tighter tolerance (shorter steps: the shadow's error, "
        f"{member.z_substeps}^{member.z_order} times the quencher's, falls with them)"
    )
    tighter = f"{tighter_tolerance} or a shorter interval"
    helps = "" if grew else f" What helps: {tighter}."
    if grew:
        text += (
            " The estimate grew faster than any power of t, as on a chaotic orbit or one near "
            "an unstable equilibrium or a separatrix, or in a burst at a close approach (Kepler "
            f"at e = 0.95 reads so at its pericentres): a shorter interval is what works, and "
            f"{tighter_tolerance} delays the saturation where the growth allows it (not in a "
            "burst: Kepler at e = 0.999999 stops at the same pericentre at any tolerance)."
        )
    if tangent_follows_saturation(task):
        # auto ran the tangent estimate after this run, which stopped
        # earlier: auto returns the run that reached furthest
        return text + helps
    if task.options.double_double and task.double_floor_at is not None:
        # The tangent estimate has no double-double form, and in double auto's
        # run before this one stopped at the floor: Kepler at e = 0.95, rtol
        # 1e-5, over 100 periods on 2001 output times stopped at t = 107 in
        # double and its shadow saturated at t = 219.6 in double-double
        # (benchmarks/shadow_saturation.txt); the tangent estimate in double
        # would stop at the floor as soon.
        return text + (
            " The tangent estimate, which has no shadow, has no double-double form, and in "
            f"double the run before this one stopped at double precision's floor at "
            f"t = {task.double_floor_at!r}." + helps
        )
    # Not a smaller max_step: it keeps the shadow within its limit without
    # making Gamma honest again (hamrkq.solve.auto._with_tangent).  The
    # tangent estimate has no double-double form: a run in double-double is
    # pointed to the quencher in double with it (QA: the pendulum from the
    # double nearest pi in double-double was offered the tangent estimate
    # alone, an OptionError with its precision).
    in_double = (
        "; it has no double-double form: with quencher_precision='double'"
        if task.options.double_double
        else ""
    )
    return text + (
        " What helps: global_error_estimate='tangent' (the error carried by the Jacobian, no "
        "shadow: more quencher steps do not change the shadow's error, the quencher's in one "
        f"step a step, {member.z_substeps}^{member.z_order} times its own{in_double})"
        + ("." if grew else f"; {tighter}.")
    )


#: The largest rounding level whose square is a double.  The quencher's
#: modelled rounding ``rho_k`` is the root of a sum of squares of ``eps``
#: times its increments (:func:`hamrkq.rkq.steps.quencher_step`,
#: docs/algorithm.md), so it overflows where those pass this, from a state of
#: about ``ROUNDING_SQUARE_LIMIT / eps`` = 6e169 on (1e169 for the oscillator
#: over 1000 time units, whose squares add up), however finite f and the
#: solution are.
ROUNDING_SQUARE_LIMIT = math.sqrt(sys.float_info.max)
#: A ratio that stopped being finite at a state whose ``eps |y|`` is at least
#: this share of :data:`ROUNDING_SQUARE_LIMIT` (``|y|`` from 6e165) is put
#: down to that overflow: the squares of a run of ``N`` steps add up to
#: ``N (eps |y| h w)^2`` (``w`` the orbit's frequency, ``h w`` below one), so
#: a million radians of an orbit at ``h w = 0.5`` overflow from ``|y|`` =
#: 8.5e166; below 6e165, only runs of 4e8 steps or more.
ROUNDING_OVERFLOW_SHARE = 1e-4


def _rounding_overflows(out: RunOutput) -> bool:
    """Whether a run whose ratio stopped being finite reached a state large
    enough for the quencher's modelled rounding to overflow
    (:data:`ROUNDING_OVERFLOW_SHARE`)."""
    return EPS * state_size(out) >= ROUNDING_OVERFLOW_SHARE * ROUNDING_SQUARE_LIMIT


#: A state this large (1e-8 of the largest double) is near overflow: a
#: non-finite value in a step from it is the state's size, not a singularity.
NEAR_OVERFLOW = 1e-8 * sys.float_info.max


def state_size(out: RunOutput) -> float:
    """The largest ``|y_k|`` over every node of a run, kept or not (its
    start too: a run that ends at t0 keeps only that)."""
    size = float(np.max(largest_state(out), initial=0.0))
    if out.y_max is not None:
        size = max(size, float(np.max(out.y_max, initial=0.0)))
    return size


def _rounding_overflowed(out: RunOutput) -> str:
    """The message for a run ended where the quencher's modelled rounding
    overflowed (:func:`_rounding_overflows`): the oscillator at ``|y|`` =
    5e199 with ``atol`` 1e199, whose f and exact solution are finite, ended
    at t0 with every member, and the message said Gamma was no longer
    finite, then blamed a chaotic orbit and named a looser tolerance and
    ``global_error_estimate='tangent'``, with no Gamma at all
    (``global_error_estimate='off'``) too."""
    return (
        f"At t = {float(out.t_last)!r} the quencher's modelled rounding is no longer finite, "
        "so the tolerance can no longer be certified; the run ends at the last node where it "
        "held. The model sums the squares of eps times the quencher's increments, and a "
        f"square overflows a double once that passes {ROUNDING_SQUARE_LIMIT:.3g}: from a "
        f"state of about 1e169 on, and the state's largest component here is "
        f"{state_size(out):.3g}. "
        "It is the state's size, not the orbit or the tolerance: a looser tolerance or "
        "another estimate of the quencher's error does not help. What works: variables "
        "rescaled to bring the state well below 1e169 (q = s Q and p = s P, with "
        "H(s Q, s P) / s^2 as the Hamiltonian: the same t)."
    )


def _estimate_diverged(out: RunOutput, task: Task) -> str:
    """The message for an estimate of Gamma that stopped being finite, or
    of the quencher's rounding (:func:`_rounding_overflowed`; without Gamma,
    ``global_error_estimate='off'``, only that can)."""
    o = task.options
    if o.gamma_name == "off" or _rounding_overflows(out):
        return _rounding_overflowed(out)
    text = (
        f"At t = {float(out.t_last)!r} the estimate of the quencher's global error (Gamma) "
        "is no longer finite, so the tolerance can no longer be certified; the run ends at "
        "the last node where it held."
    )
    if o.gamma_name != "shadow":
        return text + " A looser tolerance or a shorter interval is what works."
    member = member_of(task)
    amplification = float(member.z_substeps) ** member.z_order
    return text + (
        f" The shadow track behind the estimate runs without quenching and carries "
        f"{member.z_substeps}^{member.z_order} = {amplification:.3g} times the quencher's "
        "error; it diverged, which happens where errors grow fast along the orbit (near an "
        "unstable equilibrium or a separatrix, or on a chaotic orbit). What helps: a looser "
        "tolerance or a shorter interval; global_error_estimate='tangent' (the error carried "
        "linearly by the Jacobian, with no amplified track to diverge; about twice the cost)."
    )


def _time_floor_note(task: Task) -> str:
    """What the floor owes to the rounding of the time where ``H`` depends
    on it (:func:`hamrkq.solve.dispatch.time_rounding_limits`), or ``""``."""
    if not time_rounding_limits(task):
        return ""
    scale = time_scale(task)
    text = (
        f" H depends on t, and at |t| up to {scale:.6g} an ulp of the time is "
        f"{float(np.spacing(scale)):.2g}: the rounding of the stage times is part of this "
        "floor, in double-double too."
    )
    if not abs(task.t0) > abs(task.t_end - task.t0):
        # The span itself reaches those times: shifting it changes nothing
        # (it named "t_span shifted to start at 0" for a run from 0; QA).
        return text
    return text + (
        " Integrating from t = 0 lowers it: t_span shifted to start at 0, and H written for "
        "the shifted time, its phases moved by w t0 computed once (cos(w t + phi), "
        "phi = w t0 mod 2 pi)."
    )
