"""The RKQ family's methods by name: embedded pairs, quenchers, family members.

Prentice's RKQ algorithm runs two tracks on one mesh (J. S. C. Prentice,
arXiv:1111.6996, and his RKrvQz papers): the reported solution ``y``,
advanced by a locally extrapolated embedded pair of orders ``r < v`` (the
order-``r`` formula's local error is estimated against the order-``v`` one,
and the order-``v`` value is propagated), and the reference solution ``z``,
advanced by a "quencher" of order ``z >> v`` whose difference from ``y``
estimates the global error of ``y``.  A member of the family is named
``rk{r}{v}q{z}`` after the paper: the paper's own method is ``rk34q8``
(Kutta's RK3, the classical RK4, and an eighth-order quencher).

- :data:`PAIRS`: tableaus with embedded weights, for the ``y`` track.
- :data:`QUENCHERS`: tableaus for the ``z`` track (only ``b`` is used).
- :func:`family_members`: every member, one per pair and quencher order.

All tableaus are :class:`~hamrkq.methods.tableaus.ButcherTableau`: frozen,
cited, exact or as published, with read-only C-contiguous float64 arrays.
:func:`kernel_arrays` hands a compiled kernel the arrays it needs with one
fixed signature.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import NamedTuple

import numpy as np

from hamrkq.errors import InputTypeError, OptionError
from hamrkq.methods.dormand_prince import DORMAND_PRINCE_54
from hamrkq.methods.feagin import FEAGIN_10, FEAGIN_12
from hamrkq.methods.tableaus import (
    COOPER_VERNER_RK8,
    DOP853_PAIR,
    DOP853_RK8,
    RK3_KUTTA,
    RK4_CLASSIC,
    RK34_PAIR,
    ButcherTableau,
)
from hamrkq.methods.verner import (
    VERNER_65,
    VERNER_76,
    VERNER_87,
    VERNER_87_EFFICIENT,
    VERNER_98,
)

__all__ = [
    "ALL_TABLEAUS",
    "DEFAULT_QUENCHER_BY_ORDER",
    "MIN_ORDER_GAP",
    "PAIRS",
    "QUENCHERS",
    "FamilyMember",
    "KernelArrays",
    "family_members",
    "get_member",
    "get_pair",
    "get_quencher",
    "kernel_arrays",
]

#: Embedded pairs for the reported track, by name (read-only).  The order of
#: ``b`` is ``v``, of ``b_embedded`` is ``r``:
#:
#: - ``"rk34"``: Kutta's RK3 and the classical RK4 sharing ``k1, k2`` (the
#:   paper's pair; 5 stages).
#: - ``"dp54"``: Dormand-Prince 5(4), 7 stages, FSAL.
#: - ``"vern65"``: Verner's efficient 6(5), 9 stages, FSAL.
#: - ``"vern76"``: Verner's efficient 7(6), 10 stages.
#: - ``"vern87"``: Verner's robust 8(7), 13 stages.
#: - ``"vern98"``: Verner's efficient 9(8), 16 stages.
PAIRS: Mapping[str, ButcherTableau] = MappingProxyType(
    {
        "rk34": RK34_PAIR,
        "dp54": DORMAND_PRINCE_54,
        "vern65": VERNER_65,
        "vern76": VERNER_76,
        "vern87": VERNER_87,
        "vern98": VERNER_98,
    }
)

#: Quenchers for the reference track, by name (read-only).  ``"dop853"`` and
#: ``"cooper_verner"`` are the ``z_method`` values of the first release.
QUENCHERS: Mapping[str, ButcherTableau] = MappingProxyType(
    {
        "dop853": DOP853_RK8,
        "cooper_verner": COOPER_VERNER_RK8,
        "vern98": VERNER_98,
        "feagin10": FEAGIN_10,
        "feagin12": FEAGIN_12,
    }
)

#: The quencher a family member of order ``z`` uses.  Order 8 is DOP853's
#: formula, the paper's case as RKQ.md decides it; Cooper-Verner stays
#: available by name but does not get a member of its own, so that every
#: ``rk{r}{v}q{z}`` name means one thing.
DEFAULT_QUENCHER_BY_ORDER: Mapping[int, str] = MappingProxyType(
    {8: "dop853", 9: "vern98", 10: "feagin10", 12: "feagin12"}
)

#: A member needs ``z >= v + MIN_ORDER_GAP``: the quencher must be at least two
#: orders above the propagated solution, or its own error is not negligible
#: next to the error it is meant to estimate (Prentice's ``v << z``).
MIN_ORDER_GAP = 2

#: Every tableau in hamrkq by name (read-only), including ones that are not
#: in the family: RK3 and RK4 on their own, Verner's efficient 8(7) pair (kept
#: for comparison with the robust one) and DOP853 with its 5th-order estimator.
ALL_TABLEAUS: Mapping[str, ButcherTableau] = MappingProxyType(
    {
        t.name: t
        for t in (
            RK3_KUTTA,
            RK4_CLASSIC,
            *PAIRS.values(),
            VERNER_87_EFFICIENT,
            *QUENCHERS.values(),
            DOP853_PAIR,
        )
    }
)


@dataclass(frozen=True)
class FamilyMember:
    """One member ``RK{r}({v})Q{z}`` of the RKQ family.

    Parameters
    ----------
    name : str
        ``f"rk{r}{v}q{z}"``, e.g. ``"rk34q8"`` (the paper's method).
    pair : str
        Key of the embedded pair in :data:`PAIRS`.
    quencher : str
        Key of the quencher in :data:`QUENCHERS`.
    r, v, z : int
        Orders of the estimated (embedded) formula, the propagated formula
        and the quencher, ``r < v < z``.
    """

    name: str
    pair: str
    quencher: str
    r: int
    v: int
    z: int

    @property
    def pair_tableau(self) -> ButcherTableau:
        """The embedded pair's tableau."""
        return PAIRS[self.pair]

    @property
    def quencher_tableau(self) -> ButcherTableau:
        """The quencher's tableau."""
        return QUENCHERS[self.quencher]

    @property
    def evaluations_per_step(self) -> int:
        """Evaluations of ``f`` per accepted step on both tracks (no Jacobian)."""
        return self.pair_tableau.evaluations_per_step + self.quencher_tableau.evaluations_per_step


def _member_name(r: int, v: int, z: int) -> str:
    return f"rk{r}{v}q{z}"


def _build_members() -> tuple[FamilyMember, ...]:
    members = []
    for pair_name, pair in PAIRS.items():
        r, v = pair.embedded_order, pair.order
        for z, quencher_name in sorted(DEFAULT_QUENCHER_BY_ORDER.items()):
            if z >= v + MIN_ORDER_GAP:
                name = _member_name(r, v, z)
                members.append(FamilyMember(name, pair_name, quencher_name, r, v, z))
    return tuple(members)


_MEMBERS: Mapping[str, FamilyMember] = MappingProxyType({m.name: m for m in _build_members()})


def family_members() -> tuple[FamilyMember, ...]:
    """Every member of the RKQ family, by increasing ``v``, then ``z``.

    One member per embedded pair in :data:`PAIRS` and quencher order in
    :data:`DEFAULT_QUENCHER_BY_ORDER` with ``z >= v + MIN_ORDER_GAP``.

    Returns
    -------
    tuple of FamilyMember
    """
    return tuple(_MEMBERS.values())


def _lookup(kind: str, table: Mapping, name: object):
    if not isinstance(name, str):
        raise InputTypeError(f"{kind} name must be a str, got {type(name).__name__}: {name!r}")
    try:
        return table[name]
    except KeyError:
        valid = ", ".join(repr(k) for k in table)
        raise OptionError(f"unknown {kind} {name!r}; valid names: {valid}") from None


def get_pair(name: str) -> ButcherTableau:
    """The embedded pair called ``name`` (a key of :data:`PAIRS`).

    Raises
    ------
    OptionError
        If there is no such pair; the message lists every valid name.
    InputTypeError
        If ``name`` is not a string.
    """
    return _lookup("embedded pair", PAIRS, name)


def get_quencher(name: str) -> ButcherTableau:
    """The quencher called ``name`` (a key of :data:`QUENCHERS`).

    Raises
    ------
    OptionError
        If there is no such quencher; the message lists every valid name.
    InputTypeError
        If ``name`` is not a string.
    """
    return _lookup("quencher", QUENCHERS, name)


def get_member(name: str) -> FamilyMember:
    """The family member called ``name``, e.g. ``"rk34q8"`` or ``"rk67q9"``.

    Raises
    ------
    OptionError
        If there is no such member; the message lists every valid name.
    InputTypeError
        If ``name`` is not a string.
    """
    return _lookup("RKQ family member", _MEMBERS, name)


class KernelArrays(NamedTuple):
    """A tableau's float64 arrays with one fixed signature for a compiled kernel.

    Every array is C-contiguous, float64 and read-only.  ``b_embedded`` and
    ``b_error`` have length 0 for a tableau without embedded weights (a
    quencher), never ``None``, so a numba kernel compiles once for all.
    """

    A: np.ndarray
    b: np.ndarray
    b_embedded: np.ndarray
    b_error: np.ndarray
    c: np.ndarray
    stages: int
    fsal: bool


_EMPTY = np.zeros(0, dtype=np.float64)
_EMPTY.setflags(write=False)


def kernel_arrays(tableau: ButcherTableau) -> KernelArrays:
    """The arrays a compiled kernel takes, from any tableau.

    Parameters
    ----------
    tableau : ButcherTableau

    Returns
    -------
    KernelArrays
    """
    if not isinstance(tableau, ButcherTableau):
        raise InputTypeError(
            f"tableau must be a ButcherTableau, got {type(tableau).__name__}: {tableau!r}"
        )
    return KernelArrays(
        A=tableau.A,
        b=tableau.b,
        b_embedded=_EMPTY if tableau.b_embedded is None else tableau.b_embedded,
        b_error=_EMPTY if tableau.b_error is None else tableau.b_error,
        c=tableau.c,
        stages=tableau.stages,
        fsal=tableau.fsal,
    )
