"""The data an RKQ integration carries between steps, by name.

The step kernel (:mod:`hamrkq.rkq.loop`) runs as plain Python or compiled by
numba, so its state is plain arrays rather than objects:

- a *configuration* record (:data:`CONFIG`, one row of a structured array):
  the validated options as numbers, fixed for the run;
- a *state* record (:data:`STATE`): time, step size, counters and flags,
  updated in place by every step;
- :class:`Work`: the vectors and stage matrices (named arrays);
- :class:`Tableaus`: the coefficients of the reported pair and of the
  quencher, as float64 arrays;
- :class:`Output`: the buffers that kept nodes are written into.

Everything here is data; the codes (``QUENCH_*``, ``GAMMA_*``, ``ST_*``) are
the numbers the configuration and the status field hold.
"""

from __future__ import annotations

import operator
import struct
from typing import NamedTuple

import numpy as np

from hamrkq.rkq.jit import jitable

__all__ = [
    "CONFIG",
    "STATE",
    "Inputs",
    "Output",
    "Tableaus",
    "Work",
    "allocate_output",
    "allocate_work",
    "new_config",
    "new_state",
]

#: The smallest positive double: the step-size floor at t = 0, where 10 eps |t|
#: would be zero and let the step shrink to nothing.
MIN_SUBNORMAL = 5e-324

# Option codes.
QUENCH_NODE, QUENCH_REDO = 0, 1
RULE_COMPONENTWISE, RULE_PRENTICE = 0, 1
#: Gamma (the quencher's global error): not estimated; Richardson local errors
#: propagated by the exact linearisation of the quencher's step; the paper's
#: (I + h J) propagation; or global extrapolation from a shadow track run on a
#: mesh ``z_substeps`` times coarser.
GAMMA_OFF, GAMMA_TANGENT, GAMMA_PAPER, GAMMA_SHADOW = 0, 1, 2, 3

# Status codes (values of hamrkq.result.Status.code) and return codes of advance.
ST_RUNNING, ST_SUCCESS, ST_UNDERFLOW, ST_NON_FINITE, ST_MAX_STEPS = -1, 0, 1, 2, 3
ST_INTERRUPTED, ST_UNATTAINABLE = 4, 5
#: The run was abandoned on its projection (``method="auto"``'s first run,
#: :func:`hamrkq.rkq.auto_rules.auto_abandon_substeps`): never a final status,
#: :func:`hamrkq.solve` runs again.
ST_ABANDONED = 9
RET_DONE, RET_BUFFER_FULL, RET_BUDGET = 0, 1, 2

_I, _F = np.int64, np.float64

#: The run's options as numbers (see :func:`new_config`).
CONFIG = np.dtype(
    [
        ("quench_mode", _I),  # QUENCH_*
        ("rule", _I),  # RULE_*
        ("gamma_mode", _I),  # GAMMA_*
        ("use_z", _I),  # 1: RKQ (a quencher track); 0: the pair alone
        ("keep_every", _I),  # keep every k-th accepted node
        ("max_steps", _I),  # limit on step attempts (accepted + rejected)
        ("use_t_eval", _I),  # keep only the requested times
        ("relative", _I),  # any rtol > 0
        ("z_substeps", _I),  # quencher steps per step of the pair
        ("fsal", _I),  # the pair's last stage is f at the new node
        ("safety", _F),
        ("theta", _F),  # quench threshold
        ("max_step", _F),
        ("first_step", _F),  # 0: chosen by the heuristic (hamrkq.rkq.start)
        ("gamma_limit", _F),
        ("t_end", _F),
        ("richardson", _F),  # 2^z / (2^z - 1)
        ("shadow_scale", _F),  # z_substeps^z - 1
        ("error_exponent", _F),  # 1 / (r + 1), r the embedded (error) order
        ("beta", _F),  # PI controller: weight of the previous error
        ("witness", _I),  # 1: run the rounding witness beside the quencher
        ("witness_scale", _F),  # the witness's divergence times this estimates z's rounding
        ("project", _I),  # 1: abandon when the projection of Gamma to t_end fails
        ("t_start", _F),  # t0, for the fraction of the interval covered
        ("project_from", _F),  # the projection is made from this fraction ...
        ("project_until", _F),  # ... to this one
        ("project_limit", _F),  # abandon when the projected |Gamma| / delta exceeds this
        ("z_double_double", _I),  # 1: the quencher's stages and f in double-double
        ("dense_share", _F),  # a t_eval time closer than this share of the free step is passed
    ]
)

#: What changes from step to step.
STATE = np.dtype(
    [
        ("t", _F),
        ("t_lo", _F),  # compensation term of t (t is summed compensated)
        ("h", _F),  # the next step size to try (signed)
        ("max_ratio", _F),  # largest attainability ratio so far
        ("cached_h", _F),  # step size of the cached quencher step (redo mode)
        ("failed_h", _F),  # the step size that failed (underflow, non-finite)
        ("err_prev", _F),  # the last accepted free step's error norm (PI control)
        ("steps", _I),
        ("rejected", _I),
        ("quenches", _I),
        ("nfev", _I),
        ("njev", _I),
        ("nout", _I),  # rows of the output buffers filled
        ("status", _I),  # ST_*
        ("k1_valid", _I),  # work.k1 holds f(t, u)
        ("since_kept", _I),
        ("eval_index", _I),  # next t_eval entry
        ("last_quenched", _I),
        ("last_written", _I),  # the current node is in the output
        ("roundoff_steps", _I),  # steps whose Richardson difference was rounding
        ("last_nonfinite", _I),  # the last rejection found inf/nan
        ("redo", _I),  # this step restarted from the quencher's value
        ("z_cached", _I),  # the quencher step for cached_h is in work
        ("cached_roundoff", _I),
        ("prev_rejected", _I),
        ("bad_component", _I),  # first non-finite component found, or -1
        ("floor_ratio", _F),  # the witness's share of the ratio that ended the run
        # At an output time inside a step that ended the run: the value's own
        # rounding alone over the tolerance there (hamrkq.rkq.certify.stored_share)
        ("stored_ratio", _F),
        ("projected", _F),  # |Gamma| / delta projected to t_end when abandoned (ST_ABANDONED)
        ("t_old", _F),  # the node before the last step, while its t_eval times are pending
        ("t_old_lo", _F),
        ("dense_pending", _I),  # t_eval times inside the last step are still to be written
        ("checkpoint", _I),  # the next row CHK0 + k whose time is still ahead
        # The smallest and largest free step accepted once the controller
        # first asked for no growth (``ramped``: the first steps' growth is over):
        # their ratio, a close approach's mark, is read by the witness's
        # rules after a run (hamrkq.rkq.witness_rules.close_approach_factor).
        ("h_least", _F),
        ("h_most", _F),
        ("ramped", _I),
        # The first step size tried, |h| (hamrkq.rkq.start.begin; 0 before it,
        # or where the run ended at its start)
        ("first_h", _F),
    ]
)


class Tableaus(NamedTuple):
    """Coefficients as float64 arrays: the reported pair and the quencher.

    The pair's stages ``K[j] = f(t + c[j] h, u + h sum_l A[j, l] K[l])``
    give the propagated solution ``u + h sum b K`` and the embedded one
    ``u + h sum b_err K``; their difference sizes the steps.  The
    quencher's coefficients are double-doubles, ``Az + Az_low`` and
    ``bz + bz_low`` (see ``ButcherTableau.A_low``).
    """

    A: np.ndarray
    b: np.ndarray
    b_err: np.ndarray
    c: np.ndarray
    Az: np.ndarray
    bz: np.ndarray
    cz: np.ndarray
    Az_low: np.ndarray
    bz_low: np.ndarray


class Inputs(NamedTuple):
    """The run's numeric inputs: parameter values, tolerances, output times,
    and the parameter values the rounding witness runs with (each moved by
    about an ulp, :func:`hamrkq.rkq.arith.nudge`)."""

    params: np.ndarray
    atol: np.ndarray
    rtol: np.ndarray
    t_eval: np.ndarray
    witness_params: np.ndarray


#: Rows ``CHK0 .. CHK0 + CHECKPOINTS - 1`` of :attr:`Work.V`: the largest
#: ``|Gamma|`` over the nodes up to the fractions ``2^-(CHECKPOINTS - 1), ...,
#: 1/4, 1/2, 1`` of the interval, so that the rules after a run read how Gamma
#: grew over the second half of it from every node, not only from the kept
#: ones (``t_eval``, ``keep_every``; :func:`checkpoint_fraction`).
CHECKPOINTS = 16

#: The rows of :attr:`Work.V`, each a vector of ``d`` components.  Rows of
#: one matrix rather than separate arrays, because numba passes every array
#: of a tuple to each helper it calls: with 28 separate vectors, passing them
#: was a third of the compiled kernel's time (``docs/performance.md``).
VECTORS = (
    ("U", "the reported solution"),
    ("ZHI", "the quencher track, compensated: z = ZHI + ZLO"),
    ("ZLO", ""),
    ("GAM", "Gamma at the current node"),
    ("RHO2", "accumulated rounding variance of z"),
    ("SHI", "the shadow track (GAMMA_SHADOW), compensated"),
    ("SLO", ""),
    ("K1", "f(t, u)"),
    ("CAND", "the pair's candidate"),
    ("ERR", "the pair's error estimate"),
    ("DELTA", "tolerance per component"),
    ("YT", "stage argument"),
    ("DY", "stage argument of the tangent (its low words: the quencher in double-double)"),
    ("INC", "an increment"),
    ("INC_LO", "the other increment of the pair (and the quencher's low words)"),
    ("DINC", "tangent increment"),
    ("INCA", "Richardson half steps"),
    ("INCB", ""),
    ("MHI", "Richardson midpoint, compensated"),
    ("MLO", ""),
    ("NHI", "the quencher's candidate, compensated"),
    ("NLO", ""),
    ("NSHI", "the shadow's candidate, compensated"),
    ("NSLO", ""),
    ("WHI", "the rounding witness: the quencher with its sums reversed"),
    ("WLO", ""),
    ("NWHI", "the witness's candidate, compensated"),
    ("NWLO", ""),
    ("FLOOR", "rounding floor of z measured by the witness (running max)"),
    ("NFLOOR", "its candidate"),
    ("GNEW", "Gamma's candidate"),
    ("NOISE", "rounding of this step"),
    ("TMP", "scratch"),
    ("TMP2", "scratch"),
    ("UOLD", "the reported solution at the node before the step (t_eval times inside it)"),
    ("ZOLD", "the quencher track there, compensated"),
    ("ZOLDLO", ""),
    ("GOLD", "Gamma there"),
    ("DHI", "a dense value's quencher state between its substeps, compensated"),
    ("DLO", ""),
    ("YMAX", "each component's largest |u| over every node (kept or not)"),
    ("GMAX", "each component's largest |Gamma| over every node"),
    *((f"CHK{k}", "GMAX when t passed checkpoint_fraction(k)") for k in range(CHECKPOINTS)),
)
(
    U, ZHI, ZLO, GAM, RHO2, SHI, SLO, K1, CAND, ERR, DELTA, YT, DY, INC, INC_LO, DINC,
    INCA, INCB, MHI, MLO, NHI, NLO, NSHI, NSLO, WHI, WLO, NWHI, NWLO, FLOOR, NFLOOR,
    GNEW, NOISE, TMP, TMP2, UOLD, ZOLD, ZOLDLO, GOLD, DHI, DLO, YMAX, GMAX,
) = range(len(VECTORS) - CHECKPOINTS)  # fmt: skip
CHK0 = GMAX + 1


@jitable
def checkpoint_fraction(k):
    """The fraction of the interval of the row ``CHK0 + k``: ``2^-(CHECKPOINTS
    - 1 - k)``, ascending in ``k`` to 1 (the kernel calls it; numba compiles
    it)."""
    return 2.0 ** -(CHECKPOINTS - 1 - k)


def checkpoint_fractions() -> np.ndarray:
    """:func:`checkpoint_fraction` of every checkpoint row, ascending."""
    return np.array([checkpoint_fraction(k) for k in range(CHECKPOINTS)])


class Work(NamedTuple):
    """The vectors and stage matrices of one integration.

    ``V[ROW]`` is the vector named by a row constant of this module
    (:data:`VECTORS` says what each holds, e.g. ``V[U]`` the reported
    solution, ``V[ZHI]`` the quencher track).
    """

    V: np.ndarray  # (len(VECTORS), d)
    K: np.ndarray  # the pair's stages (s x d)
    Kz: np.ndarray  # the quencher's stages (sz x d)
    dKz: np.ndarray  # their tangents (their low words: the quencher in double-double)
    JM: np.ndarray  # a Jacobian (d x d)


class Output(NamedTuple):
    """Buffers for kept nodes (rows ``0 .. state.nout``)."""

    t: np.ndarray
    y: np.ndarray
    z: np.ndarray
    gamma: np.ndarray
    quenched: np.ndarray
    #: the quencher's rounding at each node, modelled and measured by the
    #: witness (``sqrt(RHO2) + FLOOR``): what checks after the run, at event
    #: states, count beside Gamma (:func:`hamrkq.rkq.dense.attainability`)
    rounding: np.ndarray


def allocate_work(y0: np.ndarray, stages: int, z_stages: int) -> Work:
    """Zeroed work arrays for a state of ``d = y0.size`` components, loaded
    with ``y0`` (the reported and the quencher tracks start there)."""
    d = y0.shape[0]
    work = Work(
        V=np.zeros((len(VECTORS), d)),
        K=np.zeros((stages, d)),
        Kz=np.zeros((max(z_stages, 1), d)),
        dKz=np.zeros((max(z_stages, 1), d)),
        JM=np.zeros((d, d)),
    )
    work.V[_STARTING_ROWS] = y0
    np.abs(y0, out=work.V[YMAX])
    return work


#: The rows of :attr:`Work.V` a run starts at ``y0`` (:func:`allocate_work`).
_STARTING_ROWS = [U, ZHI, SHI, WHI]


def allocate_output(rows: int, d: int, with_z: bool) -> Output:
    """Empty output buffers of ``rows`` nodes (no quencher rows without ``with_z``)."""
    zrows = rows if with_z else 0
    return Output(
        t=np.empty(rows),
        y=np.empty((rows, d)),
        z=np.empty((zrows, d)),
        gamma=np.empty((zrows, d)),
        quenched=np.zeros(zrows, dtype=np.int8),
        rounding=np.empty((zrows, d)),
    )


#: The configuration's fields, as a set and in order, and its record as
#: packed bytes (native order, no padding: CONFIG's own layout).
_CONFIG_NAMES = frozenset(CONFIG.names)
_CONFIG_VALUES = operator.itemgetter(*CONFIG.names)
_CONFIG_BYTES = struct.Struct(
    "=" + "".join("q" if CONFIG.fields[name][0] == _I else "d" for name in CONFIG.names)
)
assert _CONFIG_BYTES.size == CONFIG.itemsize


def new_config(**values: float) -> np.ndarray:
    """A one-row :data:`CONFIG` array; every field must be given."""
    if values.keys() != _CONFIG_NAMES:
        missing = _CONFIG_NAMES - set(values)
        unknown = set(values) - _CONFIG_NAMES
        raise TypeError(f"config fields missing {sorted(missing)}, unknown {sorted(unknown)}")
    # one record from a tuple in field order: a store per field costs ten
    # times as much (every solve pays this); packed as the record's bytes
    # (doubles and integers stored as they are), a third of NumPy's
    # conversion of the tuple, which remains for what struct does not take
    # as it is (a float for an integer field, which NumPy truncates)
    row = _CONFIG_VALUES(values)
    try:
        packed = _CONFIG_BYTES.pack(*row)
    except (struct.error, TypeError, OverflowError):
        return np.array([row], dtype=CONFIG)
    # (a writable buffer of them: NumPy copies a record array field by
    # field, and CONFIG's alignment is 1, so any buffer is aligned for it)
    return np.frombuffer(bytearray(packed), dtype=CONFIG)


def new_state(t0: float) -> np.ndarray:
    """A one-row :data:`STATE` array at ``t0``, running, nothing counted."""
    state = np.zeros(1, dtype=STATE)
    state[0]["t"] = t0
    state[0]["status"] = ST_RUNNING
    state[0]["bad_component"] = -1
    state[0]["h_least"] = np.inf
    return state
