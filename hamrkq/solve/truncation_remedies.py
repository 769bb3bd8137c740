"""What carries a run stopped on its quencher's truncation error further,
for the message of :func:`hamrkq.solve.unattainable.unattainable`: more
quencher steps (the rule auto's reruns use), read against how the estimate
grew over the run (like ``t^2``, exponentially, or in a first burst that one
reading cannot tell from chaos) and against the state's own growth, and the
other remedies, the most specific first.
"""

from __future__ import annotations

import numpy as np

from hamrkq.rkq.auto_rules import EXPONENTIAL_GROWTH, middle_of
from hamrkq.rkq.driver import RunOutput
from hamrkq.rkq.family import MEMBERS
from hamrkq.solve.auto import double_double_can_help, retry_substeps
from hamrkq.solve.dispatch import Task, member_of
from hamrkq.solve.shadow import largest_state

__all__ = ["SIZE_GROWTH", "growth_text", "remedies", "size_growth"]


def _retry_substeps(out: RunOutput, task: Task, factor: float) -> int | None:
    """The quencher steps per step that carry a run stopped on its
    quencher's truncation error to its end (the rule auto's reruns use,
    :func:`hamrkq.rkq.auto_rules.auto_retry_substeps`, with the estimate's
    growth ``factor`` where it is exponential), or None."""
    if task.options.gamma_name != "shadow":
        return None
    return retry_substeps(out, task, growth=factor if factor > EXPONENTIAL_GROWTH else None)


def growth_text(out: RunOutput, task: Task, factor: float, grown: tuple[float, str] | None) -> str:
    """What a stop after an exponential-looking growth of the estimate
    (``factor`` over the second half) says about it: chaos and its kin, or,
    where the state grew too (``grown``, :func:`size_growth`), the rounding
    that grows with it."""
    if grown is not None:
        size, name = grown
        text = (
            f" The estimate grew {factor:.3g}-fold over the second half of the run, while the "
            f"state grew too: {name} grew {size:.3g}-fold in size, its tolerance atol's, and the "
            "rounding of the quencher's stages grows with the size of the values (a winding "
            "angle, an escaping body, a close approach), so this need not be exponential growth"
        )
    else:
        text = (
            f" The estimate grew {factor:.3g}-fold over the second half of the "
            "run: faster than any power of t, as on a chaotic orbit or one near an unstable "
            "equilibrium, a separatrix or a singularity, where errors (the rounding too) grow "
            "like exp(lambda t)"
        )
    if _retry_substeps(out, task, factor) is not None:
        return text + "."
    burst = _burst_substeps(out, task, factor)
    if burst is not None:
        return text + (
            ", or a burst (a close approach): one reading cannot tell them apart, and on a "
            "chaotic orbit more quencher steps only delay the stop."
        )
    return text + "; more quencher steps only delay the stop."


def _burst_substeps(out: RunOutput, task: Task, factor: float) -> int | None:
    """The quencher steps per step that carry a run to its end if the
    exponential-looking growth ``factor`` its estimate read was a burst (a
    close approach) and its error grows like ``t^2`` from here, where that is
    the first such reading (``task.exponential_until``: auto's run after one
    reads a second), else None.  One reading cannot tell a burst from chaos:
    ``rk56q8`` on Kepler at e = 0.9, atol 1e-13, ``max_step`` 0.1, its
    quencher in double-double, read a 358-fold growth up to its stop at
    t = 6.27, just before the pericentre, and said more quencher steps only
    delay the stop; three carry it to the end (QA round 4, R2)."""
    if factor <= EXPONENTIAL_GROWTH or task.exponential_until is not None:
        return None
    return _retry_substeps(out, task, 1.0)


#: A component whose size grew this much over the second half of a run,
#: its tolerance atol's (not rtol's, which grows with it), grew the rounding
#: of the quencher's stages measured against that tolerance alike: the
#: pendulum going over the top from q = 0, p = 3 at atol 1e-9 (rk34q8's
#: tangent Gamma over [0, 100] reads 14 times more from q0 = 2 pi 80 than
#: from q0 = 0), whose estimate grew 59-fold as q doubled, read as chaos.
SIZE_GROWTH = 1.5


def size_growth(out: RunOutput, task: Task) -> tuple[float, str] | None:
    """The growth in size over the second half of a run of the component
    that grew most among those whose tolerance is atol's at their largest
    size, and its name, where it is at least :data:`SIZE_GROWTH`; else None.
    Measured on the returned rows up to the middle (thinned or not) against
    the largest over every node."""
    t = out.t
    if t.shape[0] < 3:
        return None
    middle, direction = middle_of(float(t[0]), float(t[-1]))
    before = (t - middle) * direction <= 0.0
    if not before.any():
        return None
    first = np.abs(out.y[before]).max(axis=0)
    whole = largest_state(out)
    fixed = (
        np.broadcast_to(task.atol, whole.shape) >= np.broadcast_to(task.rtol, whole.shape) * whole
    )
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(fixed & (first > 0.0), whole / first, 0.0)
    k = int(np.argmax(ratio))
    if not ratio[k] >= SIZE_GROWTH:
        return None
    return float(ratio[k]), task.ham.names[k]


def remedies(
    out: RunOutput, task: Task, factor: float = 1.0, grown: tuple[float, str] | None = None
) -> list[str]:
    """What carries the quencher further when its truncation error stopped
    the run, the most specific first (``factor``: the estimate's growth; an
    exponential one makes more quencher steps no remedy, unless the stop
    was close to the end; ``grown``: the state's growth with it,
    :func:`size_growth`, where the quencher in double-double helps)."""
    o = task.options
    member = member_of(task)
    exponential = factor > EXPONENTIAL_GROWTH
    remedies = []
    if exponential:
        remedies.append("a looser tolerance or a shorter interval")
        if grown is not None:
            if double_double_can_help(task, under_cap=True):
                remedies.append(
                    "quencher_precision='double-double' (the quencher's stages and f in "
                    "double-double do not round with the size of the values)"
                )
            elif not task.auto and not task.options.double_double:
                remedies.append(
                    "method='auto', which runs the quencher in double-double where its "
                    "rounding stops a run"
                )
    substeps = _retry_substeps(out, task, factor)
    burst = None if substeps is not None else _burst_substeps(out, task, factor)
    if substeps is not None or burst is not None:
        if burst is not None:
            how = "if the growth was a burst and its error grows like t^2 from here"
        elif exponential:
            how = "if its error keeps growing as it did over the second half of the run"
        else:
            how = "if its error keeps growing like t^2, as on a periodic orbit"
        substeps = substeps or burst
        remedies.append(
            f"z_substeps={substeps} (quencher steps per step, {member.z_substeps} in this run: "
            f"its error falls like m^-{member.z_order}, and {substeps} carries it to the end "
            f"{how})"
        )
    if not task.auto and burst is not None:
        remedies.append(
            "method='auto', which runs again with more quencher steps after a first such "
            "reading and stops after a second"
        )
    if not task.auto and not exponential:
        remedies.append(
            "method='auto', which chooses a member and runs again with more quencher steps "
            "when a run stops on the quencher's truncation error"
        )
    keep = (
        # a max_step alone makes the default estimate the tangent one: on
        # Henon-Heiles at 1e-10 auto's run with half its mean step then
        # stopped at t = 71 where its own reached 185, and with the shadow
        # kept reached 339 (found by QA)
        " with global_error_estimate='shadow' (a max_step alone makes the estimate the "
        "tangent one)"
        if o.gamma_name == "shadow"
        else ""
    )
    remedies.append(
        f"a smaller max_step{keep} (the quencher's error falls like h^{member.z_order})"
    )
    better = [name for name in MEMBERS if name not in (o.method, "rk34") and MEMBERS[name].use_z]
    if better:
        remedies.append(f"another member of the family ({', '.join(map(repr, better))})")
    if not exponential:
        remedies.append("a looser tolerance only if the quencher's error grows with the step")
    return remedies
