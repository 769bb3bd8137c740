"""Members of the RKQ family: which pair, which quencher, how they are run.

A member ``rk{r}{v}q{z}`` (Prentice's RKrvQz) reports the order-``v``
solution of an embedded pair whose order-``r`` companion sizes the steps
(local extrapolation), and quenches it with a track of order ``z`` run over
the same steps (``z_substeps`` quencher steps per step of the pair).
:class:`Member` turns that choice into the arrays the kernel takes.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field, replace
from fractions import Fraction

import numpy as np

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
from hamrkq.rkq.witness_rules import STAGE_ROUNDING_WEIGHTS

__all__ = ["MEMBERS", "Z_METHODS", "Member", "get_member", "merge_pair", "track_name"]


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


#: The quencher's arrays of a member without one: never read, and read-only
#: like every tableau's, so that the kernel's argument types are the same
#: (writeable, they made numba compile a second kernel for the pair alone,
#: 7.6 s on an empty cache, counted as integration; found by QA).
_NO_QUENCHER = (_read_only(np.zeros((1, 1))), _read_only(np.zeros(1)), _read_only(np.zeros(1)))


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
            Az, bz, cz = _NO_QUENCHER
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

    @functools.cached_property
    def stage_rounding_dominates(self) -> bool:
        """Whether the quencher's weights magnify the rounding of its stage
        values so much that the rounding witness runs at every tolerance
        (:data:`STAGE_ROUNDING_WEIGHTS`)."""
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

#: The paper's method: RK3(4) with DOP853's 8th-order formula as quencher.
PAPER_METHOD = "rk34q8"

#: The family, by name.  ``rk34q8`` is the paper's method (RK3(4) with the
#: 8th-order formula of DOP853 as quencher); ``rk34`` is its pair alone.
MEMBERS: dict[str, Member] = {
    PAPER_METHOD: Member(
        PAPER_METHOD,
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


@functools.lru_cache(maxsize=256)  # members are immutable; a solve asks several times
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


def has_quencher(method: str) -> bool:
    """Whether ``method`` runs a quencher track (and so an estimate Gamma):
    ``"auto"`` and every member but the pairs alone; False for a name outside
    the family."""
    member = MEMBERS.get(method)
    return method == "auto" or (member is not None and member.use_z)


def track_name(method: str) -> str:
    """What the paper calls the RK8 track, named by the order of the
    method's quencher: ``"RK8 track"`` for ``rk34q8``, ``"RK12 track"`` for
    ``rk78q12`` (and ``"RK8 track"`` for a method outside the family, the
    SciPy form of RK34Q8)."""
    member = MEMBERS.get(method)
    order = member.z_order if member is not None and member.use_z else 8
    return f"RK{order} track"
