"""The kernel's configuration record of a run: :class:`Settings` (the run
options, validated) and :func:`kernel_config`, which makes the record
(:data:`~hamrkq.rkq.layout.CONFIG`) from a member and the settings, once
per member and settings and copied with each run's ``t0`` and ``t_end``.
:class:`hamrkq.rkq.driver.Integration` runs with it.
"""

from __future__ import annotations

import math
import operator
import struct
from dataclasses import dataclass
from dataclasses import fields as dataclass_fields

import numpy as np

from hamrkq.rkq.auto_rules import AUTO_PROJECT_FROM, AUTO_PROJECT_SHARE, AUTO_PROJECT_UNTIL
from hamrkq.rkq.family import Member
from hamrkq.rkq.layout import CONFIG, GAMMA_SHADOW, GAMMA_TANGENT, new_config
from hamrkq.rkq.witness_rules import WITNESS_SAFETY

__all__ = ["DENSE_SHARE", "NATIVE_DOUBLE", "Settings", "kernel_config", "member_config"]

#: A ``t_eval`` time closer to the node a step starts from than this share of
#: the free step is not landed on: the step passes it, and the value there is
#: dense output (one quencher step from the nearer node,
#: :func:`hamrkq.rkq.loop.write_dense`).  Landing on every time made as many
#: steps as times (Kepler e = 0.6 with 50 001 output times: 50 000 steps
#: where 402 carry the tolerance); landing on a time far into the step costs
#: less than a dense value (``benchmarks/dense_t_eval.py`` chose the share).
DENSE_SHARE = 0.75


@dataclass(frozen=True)
class Settings:
    """Validated run options, as the kernel's configuration needs them."""

    quench: int
    rule: int
    gamma: int
    safety: float = 0.9
    theta: float = 1.0
    max_step: float = math.inf
    max_steps: int = 1_000_000
    gamma_limit: float = 0.05
    keep_every: int = 1
    t_eval: np.ndarray | None = None
    first_step: float | None = None
    witness: bool = False  # the rounding witness beside the shadow (GAMMA_SHADOW only)
    #: Abandon the run when Gamma projected to t_end fails (status
    #: ST_ABANDONED; method="auto", :func:`hamrkq.rkq.auto_rules.auto_abandon_substeps`).
    project: bool = False
    #: The quencher's stages and f in double-double (GAMMA_SHADOW only; the
    #: functions' ``tangent`` is then ``rhs_dd``, hamrkq.backends.dd_printer).
    double_double: bool = False
    #: A ``t_eval`` time closer than this share of the free step is passed,
    #: its value from dense output (:data:`DENSE_SHARE`; 0: every time is landed on).
    dense_share: float = DENSE_SHARE


#: :func:`member_config` of the members met so far, by id (with the member,
#: so that an id is not reused while it is kept).
_MEMBER_CONFIGS: dict[int, tuple[Member, dict[str, float]]] = {}


def member_config(member: Member) -> dict[str, float]:
    """The fields of the kernel's configuration a member fixes, computed once
    per member (members are immutable; ``richardson`` alone, a Fraction,
    took microseconds of every run)."""
    known = _MEMBER_CONFIGS.get(id(member))
    if known is not None and known[0] is member:
        return known[1]
    fields = {
        "use_z": int(member.use_z),
        "z_substeps": member.z_substeps,
        "fsal": int(member.fsal),
        "richardson": member.richardson,
        "shadow_scale": member.shadow_scale,
        "error_exponent": 1.0 / (member.error_order + 1),
        "beta": member.beta,
    }
    if len(_MEMBER_CONFIGS) >= 256:  # members made on the fly (replace): bounded
        _MEMBER_CONFIGS.clear()
    _MEMBER_CONFIGS[id(member)] = (member, fields)
    return fields


#: :func:`kernel_config`'s records made so far, as their bytes with ``t_start``
#: and ``t_end`` zero, by the values that decide the rest (with the member,
#: so that its id is not reused while it is kept).
_CONFIGS: dict[tuple, tuple[Member, bytes]] = {}

#: Where ``t_start`` and ``t_end`` are in a configuration record's bytes,
#: and their format (a double in native order, as ``new_config`` packs it).
_T_START, _T_END = CONFIG.fields["t_start"][1], CONFIG.fields["t_end"][1]
NATIVE_DOUBLE = struct.Struct("=d")

#: The settings that decide a configuration record: every field of
#: :class:`Settings` but ``t_eval`` (the times go to the kernel apart, and an
#: array is not hashable), read at once, so that a new field is in the key;
#: and where the ones declared float are (a zero there is not remembered: a
#: key does not tell 0.0 from -0.0, nor from an int 0).
_KEYED_SETTINGS = [f for f in dataclass_fields(Settings) if f.name != "t_eval"]
_SETTINGS_KEY = operator.attrgetter(*(f.name for f in _KEYED_SETTINGS))
_FLOAT_SETTINGS = operator.attrgetter(*(f.name for f in _KEYED_SETTINGS if "float" in str(f.type)))


def kernel_config(
    member: Member,
    settings: Settings,
    gamma: int,
    use_teval: int,
    relative: int,
    t0: float,
    t_end: float,
    remember: bool = True,
) -> np.ndarray:
    """The kernel's configuration record of a run of ``member`` with
    ``settings`` from ``t0`` to ``t_end`` (:func:`~hamrkq.rkq.layout.new_config`
    of its fields).

    ``remember``: made once per member and settings (every run of a solve,
    and of an ensemble's members, has the same ones) and copied with the
    run's ``t0`` and ``t_end``, which building and checking the record's 33
    fields by keyword took 8 us of a tiny problem's call.  The same bytes:
    ``t0`` and ``t_end`` are packed as ``new_config`` packs a double, and a
    setting that is zero, whose sign a key does not tell apart, or that is
    not hashable, is made afresh."""
    if remember:
        values = _SETTINGS_KEY(settings)
        key = (id(member), gamma, use_teval, relative, *values)
        try:
            known = _CONFIGS.get(key)
        except TypeError:  # a setting that is not hashable (a 0-d array, say)
            known, remember = None, False
        zero = 0.0 in _FLOAT_SETTINGS(settings)
        if (known is None or known[0] is not member) and remember and not zero:
            made = kernel_config(member, settings, gamma, use_teval, relative, 0.0, 0.0, False)
            if len(_CONFIGS) >= 256:  # settings made on the fly: bounded
                _CONFIGS.clear()
            known = _CONFIGS[key] = (member, made.tobytes())
        if known is not None and known[0] is member:
            record = bytearray(known[1])
            NATIVE_DOUBLE.pack_into(record, _T_START, t0)
            NATIVE_DOUBLE.pack_into(record, _T_END, t_end)
            # (a writable buffer: CONFIG's alignment is 1, as new_config's own record)
            return np.frombuffer(record, dtype=CONFIG)
    return new_config(
        **member_config(member),
        quench_mode=settings.quench,
        rule=settings.rule,
        gamma_mode=gamma,
        keep_every=settings.keep_every,
        max_steps=settings.max_steps,
        use_t_eval=use_teval,
        relative=relative,
        safety=settings.safety,
        theta=settings.theta,
        max_step=settings.max_step,
        first_step=0.0 if settings.first_step is None else float(settings.first_step),
        gamma_limit=settings.gamma_limit,
        t_end=t_end,
        witness=int(settings.witness and gamma in (GAMMA_SHADOW, GAMMA_TANGENT)),
        witness_scale=WITNESS_SAFETY,
        project=int(settings.project and member.use_z),
        t_start=t0,
        project_from=AUTO_PROJECT_FROM,
        project_until=AUTO_PROJECT_UNTIL,
        project_limit=AUTO_PROJECT_SHARE * settings.gamma_limit,
        z_double_double=int(settings.double_double and gamma == GAMMA_SHADOW),
        dense_share=settings.dense_share,
    )
