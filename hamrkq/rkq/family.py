"""Members of the RKQ family: which pair, which quencher, how they are run.

A member ``rk{r}{v}q{z}`` (Prentice's RKrvQz) reports the order-``v``
solution of an embedded pair whose order-``r`` companion sizes the steps
(local extrapolation), and quenches it with a track of order ``z`` run over
the same steps (``z_substeps`` quencher steps per step of the pair).
:class:`Member` turns that choice into the arrays the kernel takes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from fractions import Fraction

import numpy as np

from hamrkq._tolerance import component_tolerance
from hamrkq.errors import OptionError
from hamrkq.methods import registry
from hamrkq.methods.tableaus import (
    COOPER_VERNER_RK8,
    DOP853_RK8,
    RK3_KUTTA,
    RK4_CLASSIC,
    ButcherTableau,
)
from hamrkq.rkq.layout import Tableaus

__all__ = [
    "MEMBERS",
    "STAGE_ROUNDING_WEIGHTS",
    "Member",
    "auto_abandon_substeps",
    "auto_member",
    "auto_retry_substeps",
    "get_member",
    "merge_pair",
    "needs_witness",
    "tightest_tolerance",
]


def _read_only(values) -> np.ndarray:
    array = np.array(values, dtype=np.float64, order="C")
    array.setflags(write=False)
    return array


def _shared_stages(high: ButcherTableau, low: ButcherTableau) -> int:
    """Leading stages the two methods have in common (equal nodes and rows)."""
    shared = 0
    for j in range(min(high.stages, low.stages)):
        if high.c_exact[j] != low.c_exact[j] or any(
            high.A_exact[j][k] != low.A_exact[j][k] for k in range(j)
        ):
            break
        shared = j + 1
    return shared


def merge_pair(high: ButcherTableau, low: ButcherTableau) -> tuple[np.ndarray, ...]:
    """One tableau evaluating two methods that share their first stages.

    The stages are ``high``'s, then ``low``'s own stages after the shared
    ones; the weights ``b`` are ``high``'s (zero on ``low``'s own stages) and
    ``b_err`` are ``low``'s.  For Kutta's RK3 and the classical RK4 (two
    shared stages) that is 5 stages, one step of both methods.

    Returns
    -------
    (A, b, b_err, c) : read-only float64 arrays
    """
    shared = _shared_stages(high, low)
    s = high.stages + low.stages - shared
    index = list(range(shared)) + [high.stages + k for k in range(low.stages - shared)]
    A = np.zeros((s, s))
    A[: high.stages, : high.stages] = high.A
    c = np.zeros(s)
    c[: high.stages] = high.c
    b = np.zeros(s)
    b[: high.stages] = high.b
    b_err = np.zeros(s)
    for j in range(low.stages):
        b_err[index[j]] = low.b[j]
        if j >= shared:
            c[index[j]] = low.c[j]
            for k in range(j):
                A[index[j], index[k]] = low.A[j, k]
    return tuple(_read_only(x) for x in (A, b, b_err, c))


@dataclass(frozen=True)
class Member:
    """One member of the family, ready for the kernel.

    Parameters
    ----------
    name : str
        ``"rk34q8"``, ``"rk34"``, ...
    summary : str
        One line for listings and error messages.
    pair : tuple of arrays
        ``(A, b, b_err, c)`` of the reported pair (:func:`merge_pair`).
    order : int
        Order ``v`` of the propagated (reported) solution.
    error_order : int
        Order ``r`` of the companion that sizes the steps.
    quencher : ButcherTableau or None
        The quencher (None: the pair alone, no quenching).
    z_substeps : int
        Quencher steps per step of the pair.
    fsal : bool
        The pair's last stage is ``f`` at the new node.
    beta : float
        Weight of the previous error in the PI step-size controller (0: plain).
    gamma : str
        The default ``global_error_estimate`` (how Gamma is estimated).
    """

    name: str
    summary: str
    pair: tuple
    order: int
    error_order: int
    quencher: ButcherTableau | None = None
    z_substeps: int = 1
    fsal: bool = False
    beta: float = 0.0
    gamma: str = "tangent"
    tableaus: Tableaus = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        A, b, b_err, c = self.pair
        if self.quencher is not None:
            q = self.quencher
            Az, bz, cz, Az_low, bz_low = q.A, q.b, q.c, q.A_low, q.b_low
        else:
            Az, bz, cz = np.zeros((1, 1)), np.zeros(1), np.zeros(1)
            Az_low, bz_low = Az, bz
        arrays = (A, b, b_err, c, Az, bz, cz, Az_low, bz_low)
        tableaus = Tableaus(*(np.require(x, np.float64, ("C",)) for x in arrays))
        object.__setattr__(self, "tableaus", tableaus)

    @property
    def use_z(self) -> bool:
        """Whether the member has a quencher track."""
        return self.quencher is not None

    @property
    def z_order(self) -> int:
        """Order of the quencher (0 without one)."""
        return self.quencher.order if self.quencher is not None else 0

    @property
    def z_stages(self) -> int:
        """Stages of the quencher (0 without one)."""
        return self.quencher.stages if self.quencher is not None else 0

    @property
    def richardson(self) -> float:
        """``2^z / (2^z - 1)``: Richardson's factor for the quencher's local error."""
        if not self.use_z:
            return 0.0
        return float(Fraction(2**self.z_order, 2**self.z_order - 1))

    @property
    def stage_rounding_dominates(self) -> bool:
        """Whether the quencher's weights magnify the rounding of its stage
        values so much that the rounding witness must round them
        stochastically to see it (:data:`STAGE_ROUNDING_WEIGHTS`)."""
        if not self.use_z:
            return False
        return float(np.abs(self.quencher.b).sum()) > STAGE_ROUNDING_WEIGHTS

    @property
    def shadow_scale(self) -> float:
        """``m^z - 1``: the shadow track's error over the quencher's, minus one."""
        if not self.use_z or self.z_substeps < 2:
            return 1.0
        return float(self.z_substeps**self.z_order - 1)

    def evaluations_per_step(self, gamma: str, witness: bool = False) -> tuple[int, int]:
        """Right-hand-side and Jacobian evaluations of one accepted step
        (without the ones a first-same-as-last stage saves); ``witness``: the
        rounding witness runs beside the shadow."""
        s = self.pair[1].shape[0]
        nfev = s
        if not self.use_z:
            return nfev, 0
        m, sz = self.z_substeps, self.z_stages
        nfev += m * sz
        if gamma == "off":
            return nfev, 0
        if gamma == "shadow":
            return nfev + sz + (m * sz if witness else 0), 0
        nfev += m * (2 * sz - 1)
        return nfev, m * sz if gamma == "tangent" else m


_RK34 = merge_pair(RK4_CLASSIC, RK3_KUTTA)

#: The family, by name.  ``rk34q8`` is the paper's method (RK3(4) with the
#: 8th-order formula of DOP853 as quencher); ``rk34`` is its pair alone.
MEMBERS: dict[str, Member] = {
    "rk34q8": Member(
        "rk34q8",
        "RKQ: RK3/RK4 local extrapolation with an RK8 quencher (Prentice)",
        _RK34,
        order=4,
        error_order=3,
        quencher=DOP853_RK8,
    ),
    "rk34": Member(
        "rk34",
        "RK3/RK4 local extrapolation only (the paper's comparison)",
        _RK34,
        order=4,
        error_order=3,
    ),
}

#: The higher-order members run the quencher in two steps per step of the pair,
#: and estimate Gamma by global extrapolation from a shadow track on the pair's
#: own mesh (one quencher step per step): the shadow's error is 2^z times the
#: quencher's, so their difference over 2^z - 1 is the quencher's error.
FAMILY_Z_SUBSTEPS = 2
#: PI control of the higher-order pairs' steps (Hairer, Norsett & Wanner's beta).
FAMILY_BETA = 0.04


def _from_registry(spec: registry.FamilyMember) -> Member:
    pair = spec.pair_tableau
    quencher = spec.quencher_tableau
    summary = (
        f"RKQ: {pair.name} pair ({spec.r}({spec.v}), local extrapolation) with the "
        f"{quencher.name} quencher (order {spec.z})"
    )
    return Member(
        spec.name,
        summary,
        (pair.A, pair.b, pair.b_embedded, pair.c),
        order=spec.v,
        error_order=spec.r,
        quencher=quencher,
        z_substeps=FAMILY_Z_SUBSTEPS,
        fsal=pair.fsal,
        beta=FAMILY_BETA,
        gamma="shadow",
    )


for _spec in registry.family_members():
    if _spec.name not in MEMBERS:
        MEMBERS[_spec.name] = _from_registry(_spec)

#: Quenchers ``z_method`` may name for the order-8 members.
Z_METHODS: dict[str, ButcherTableau] = {"dop853": DOP853_RK8, "cooper_verner": COOPER_VERNER_RK8}


def get_member(name: str, z_method: str | None = None, z_substeps: int | None = None) -> Member:
    """The family member ``name`` (with its quencher replaced by ``z_method``
    and its number of quencher steps per step by ``z_substeps``).

    Raises
    ------
    OptionError
        An unknown name, listing the valid ones.
    """
    member = MEMBERS.get(name)
    if member is None:
        valid = ", ".join(repr(k) for k in MEMBERS)
        raise OptionError(f"method={name!r} is not an RKQ family member; valid: {valid}")
    changes = {}
    if z_method is not None and member.use_z and member.z_order == 8:
        if Z_METHODS[z_method] is not member.quencher:
            changes["quencher"] = Z_METHODS[z_method]
    if z_substeps is not None and member.use_z and z_substeps != member.z_substeps:
        changes["z_substeps"] = z_substeps
    return replace(member, **changes) if changes else member


#: ``method="auto"``: Verner's robust 8(7) pair with Feagin's 12th-order
#: quencher below :data:`AUTO_LARGE_DIM` state variables, chosen by the
#: measurements in ``benchmarks/family.py`` (the fewest evaluations that reach
#: the tolerance with SUCCESS, every node within 1.05 of it, on prentice2011
#: and Kepler) ...
AUTO_MEMBER = "rk78q12"
#: ... and Verner's 7(6) pair with Verner's 9th-order quencher from
#: :data:`AUTO_LARGE_DIM` on: fewer evaluations on every large catalogue
#: problem at 1e-6 to 1e-9 (the outer solar system 11 to 20 %, the Pleiades 7
#: to 19 %, the FPU chain 6 to 23 %; ``benchmarks/auto_member.md``; at 1e-10
#: the Pleiades take 7 % more).  Small systems are split: fewer on most short
#: runs, but 11 to 53 % more on prentice2011, whose 600 periods need the
#: 12th-order quencher, so they keep :data:`AUTO_MEMBER`.  What decides is
#: the number of periods, which auto cannot know before the run.
AUTO_LARGE_MEMBER = "rk67q9"
AUTO_LARGE_DIM = 12
#: Quencher steps per step of ``method="auto"``'s first run.  Enough for a
#: few dozen orbits at any tolerance (Kepler e = 0.6 over 10 orbits at 1e-6:
#: the quencher's true error ends at 6.8e-9, 0.14 of the limit), and a run that
#: needs more learns it from its first 2 % (:func:`auto_abandon_substeps`) or
#: from where it stops (:func:`auto_retry_substeps`) and runs again.  The
#: pair's steps grow like tol^(1/8) and the quencher's error like h^12, so
#: the quencher's error relative to the tolerance grows like tol^(1/2):
#: loose tolerances and long intervals need more steps (prentice2011 over
#: [0, 4000] in two steps a step stops at t = 530 at 1e-6 and t = 2693 at 1e-8).
AUTO_FIRST_SUBSTEPS = 2


def tightest_tolerance(atol: np.ndarray, rtol: np.ndarray, y: np.ndarray) -> float:
    """The smallest :func:`hamrkq._tolerance.component_tolerance` at the state ``y`` (infinite
    for no components): what ``method="auto"`` and the rounding witness are
    chosen by, at ``y0``."""
    return float(np.min(component_tolerance(atol, rtol, y), initial=np.inf))


def auto_member(dim: int) -> tuple[str, int]:
    """The member ``method="auto"`` runs for a system of ``dim`` state
    variables, and its first run's quencher steps per step.  Both members
    estimate Gamma with the shadow track and start with
    :data:`AUTO_FIRST_SUBSTEPS` (``tests/test_family.py``)."""
    name = AUTO_LARGE_MEMBER if dim >= AUTO_LARGE_DIM else AUTO_MEMBER
    return name, AUTO_FIRST_SUBSTEPS


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


#: The most quencher steps per step ``method="auto"`` tries.
AUTO_MAX_SUBSTEPS = 12


def auto_retry_substeps(
    substeps: int, z_order: int, gamma_ratio: float, gamma_limit: float, reached: float
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
    ``m`` grows to ``ceil(m r^(1/z))``, at least by one.

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

    Returns
    -------
    int or None
        None when the stop was not the quencher's truncation error (its
        estimate is below half the limit: rounding stopped it, and more
        quencher steps do not help) or when ``AUTO_MAX_SUBSTEPS`` is reached.
    """
    if not (0.0 < reached < 1.0) or not gamma_ratio >= 0.5 * gamma_limit:
        return None
    return _grown_substeps(substeps, z_order, gamma_ratio / reached**2, gamma_limit)


def _grown_substeps(substeps: int, z_order: int, projected: float, gamma_limit: float):
    """``ceil(m r^(1/z))``, at least ``m + 1`` and at most
    :data:`AUTO_MAX_SUBSTEPS` (None at the most), for a quencher whose error
    at ``t_end`` is projected to be ``projected`` times the tolerance:
    ``r = 2 projected / gamma_limit`` leaves half the limit to spare."""
    if substeps >= AUTO_MAX_SUBSTEPS:
        return None
    needed = 2.0 * projected / gamma_limit
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
    (``hamrkq.rkq.loop.projected_ratio``).  A run whose projection exceeds
    :data:`AUTO_PROJECT_SHARE` of ``gamma_limit`` at a node between :data:`AUTO_PROJECT_FROM` and
    :data:`AUTO_PROJECT_UNTIL` of the interval is abandoned there and run
    again with the quencher steps :func:`auto_retry_substeps` would choose at
    its stop, without running to it: prentice2011 at 1e-6 in 2 steps a step
    stops at t = 530 of 4000, and is projected at 46 times the limit from
    t = 80.  On a chaotic orbit the error grows faster than the projection,
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
