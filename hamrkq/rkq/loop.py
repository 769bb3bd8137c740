"""The RKQ step loop: one source for the interpreted and the compiled backend.

:func:`advance` implements Prentice's RKQ algorithm (J.S.C. Prentice,
arXiv:1111.6996; ``docs/algorithm.md`` explains it in plain words) for any
member of the family: an embedded pair with local extrapolation for the
reported solution ``u``, a quencher track ``z`` on the same mesh (in
``z_substeps`` steps per step of the pair), Gamma (the quencher's estimated
global error), and quenching of ``u`` to ``z`` where they differ by more than
the tolerance.  Without a quencher (``use_z = 0``) it is the pair alone.

Conventions (so that numba compiles it as written, see
:mod:`hamrkq.backends.compiled`): functions over float64 arrays, ints and
floats; no objects, closures, exceptions or allocation; the right-hand side is
``rhs(t, y, params, out)``, the Jacobian ``jac(t, y, params, out)``, and
``tangent(t, y, params, v, out, dout, JM)`` gives ``f`` and ``J v`` at one
point.  The state is explicit and named (:mod:`hamrkq.rkq.layout`), so
:func:`advance` runs in chunks: it returns when the interval is done, when its
output buffer is full, or when ``budget`` step attempts have been made, and
the driver (:mod:`hamrkq.rkq.driver`) grows the output, reports progress and
turns Ctrl-C into an interrupted status.

``max_steps`` limits step attempts, accepted plus rejected, over the whole
run (the state's counters carry across calls).
"""

from __future__ import annotations

import math

from hamrkq._floats import EPS
from hamrkq.rkq import arith, steps
from hamrkq.rkq.jit import borrow, jitable
from hamrkq.rkq.layout import (
    CAND,
    DELTA,
    ERR,
    FLOOR,
    GAM,
    GNEW,
    K1,
    MIN_SUBNORMAL,
    NFLOOR,
    NHI,
    NLO,
    NOISE,
    NSHI,
    NSLO,
    NWHI,
    NWLO,
    QUENCH_REDO,
    RET_BUDGET,
    RET_BUFFER_FULL,
    RET_DONE,
    RHO2,
    SHI,
    SLO,
    ST_ABANDONED,
    ST_MAX_STEPS,
    ST_NON_FINITE,
    ST_RUNNING,
    ST_SUCCESS,
    ST_UNATTAINABLE,
    ST_UNDERFLOW,
    TMP2,
    WHI,
    WLO,
    ZHI,
    ZLO,
    U,
)

# Step-size control (Hairer, Norsett & Wanner, Solving ODEs I, II.4).
MIN_FACTOR = 0.2  # never shrink by more than 5x on one rejection
MAX_FACTOR = 5.0  # never grow by more than 5x on one acceptance
#: A step shorter than this many ulps of t cannot advance t reliably.
FLOOR_ULPS = 10.0


@jitable
def write_node(t, quenched, work, out, state, use_z):
    """Append the current node to the output buffers."""
    n = state["nout"]
    out.t[n] = t
    arith.copy(work.V[U], out.y[n])
    if use_z:
        arith.copy(work.V[ZHI], out.z[n])
        arith.copy(work.V[GAM], out.gamma[n])
        out.quenched[n] = quenched
    # Count the node only once it is complete: an interrupt never leaves half a row.
    state["nout"] = n + 1
    state["last_written"] = 1


@jitable
def stop(status, work, out, state, cfg):
    """End the run at the current (last accepted) node, which is kept unless
    only ``t_eval`` times are kept."""
    if not state["last_written"] and not cfg["use_t_eval"]:
        quenched = 1 if (state["last_quenched"] or state["redo"]) else 0
        write_node(state["t"], quenched, work, out, state, cfg["use_z"])
    state["status"] = status
    return RET_DONE


@jitable
def reject(state, h, factor, nonfinite):
    """Count a rejected attempt and shrink the step."""
    state["h"] = h * factor
    state["rejected"] += 1
    state["prev_rejected"] = 1
    state["last_nonfinite"] = nonfinite


@jitable
def step_target(cfg, state, t_eval):
    """The time the next step must not pass: the next ``t_eval`` entry or the end."""
    if cfg["use_t_eval"] and state["eval_index"] < t_eval.shape[0]:
        return t_eval[state["eval_index"]]
    return cfg["t_end"]


@jitable
def growth_factor(cfg, state, err):
    """The next step's factor after an accepted error norm ``err`` (PI control,
    Hairer, Norsett & Wanner, Solving ODEs I, II.4 (4.13); ``beta = 0`` is the
    plain controller)."""
    if err == 0.0:
        return MAX_FACTOR
    alpha = cfg["error_exponent"] - 0.75 * cfg["beta"]
    factor = cfg["safety"] * err**-alpha
    if cfg["beta"] > 0.0:
        factor *= max(state["err_prev"], 1e-4) ** cfg["beta"]
    return min(MAX_FACTOR, factor)


@jitable
def attainability(work, problem, cfg, unew):
    """max_k (|Gamma_k| + rho_k + eps |z_k| + floor_k) / delta_k at the
    candidate node: the quencher's estimated error, its accumulated rounding
    (modelled, and measured by the witness when it runs) and the rounding of
    the stored value, against the tolerance at the new solution ``unew``."""
    V = work.V
    delta = V[DELTA]
    arith.tolerance(problem.atol, problem.rtol, unew, unew, cfg["relative"], cfg["rule"], delta)
    top = -math.inf
    for i in range(unew.shape[0]):
        rho = math.sqrt(V[RHO2, i] + V[NOISE, i])
        value = (((rho + abs(V[NHI, i]) * EPS) + abs(V[GNEW, i])) + V[NFLOOR, i]) / delta[i]
        if value != value:
            return value
        if value > top:
            top = value
    return top


@jitable
def projected_ratio(work, cfg, t_new):
    """``max_k |Gamma_k| / delta_k`` at the candidate node projected to
    ``t_end`` as growing like ``t^2`` (a periodic orbit's phase error), from
    a node between ``project_from`` and ``project_until`` of the interval;
    -1 elsewhere (:func:`hamrkq.rkq.auto_rules.auto_abandon_substeps`).  Uses
    ``V[DELTA]`` as :func:`attainability` left it."""
    reached = (t_new - cfg["t_start"]) / (cfg["t_end"] - cfg["t_start"])
    if not (cfg["project_from"] <= reached <= cfg["project_until"]):
        return -1.0
    V = work.V
    top = 0.0
    for i in range(V.shape[1]):
        value = abs(V[GNEW, i]) / V[DELTA, i]
        if value > top:
            top = value
    return top / (reached * reached)


@jitable
def commit_quencher(work, cfg, state):
    """The quencher's candidate becomes the current track."""
    V = work.V
    for new, current in ((NHI, ZHI), (NLO, ZLO), (NSHI, SHI), (NSLO, SLO), (GNEW, GAM)):
        arith.copy(V[new], V[current])
    if cfg["witness"]:
        for new, current in ((NWHI, WHI), (NWLO, WLO), (NFLOOR, FLOOR)):
            arith.copy(V[new], V[current])
    for i in range(V.shape[1]):
        V[RHO2, i] += V[NOISE, i]
    state["roundoff_steps"] += state["cached_roundoff"]
    state["z_cached"] = 0


@jitable
def advance_time(state, h, clipped, target):
    """t + h by compensated summation, or exactly the target of a clipped step."""
    t = state["t"]
    if clipped:
        state["t"] = target
        state["t_lo"] = 0.0
        return
    b = h + state["t_lo"]
    t_new = t + b
    bb = t_new - t
    state["t_lo"] = (t - (t_new - bb)) + (b - bb)
    state["t"] = t_new


@jitable
def keep_node(cfg, state, work, out, t_eval, quenched, done):
    """Write the new node if it is kept (every ``keep_every``-th, the last, or
    a ``t_eval`` time)."""
    if cfg["use_t_eval"]:
        index = state["eval_index"]
        if index < t_eval.shape[0] and state["t"] == t_eval[index]:
            write_node(state["t"], quenched, work, out, state, cfg["use_z"])
            state["eval_index"] = index + 1
        return
    state["since_kept"] += 1
    if state["since_kept"] >= cfg["keep_every"] or done:
        write_node(state["t"], quenched, work, out, state, cfg["use_z"])
        state["since_kept"] = 0


@jitable
def advance(rhs, tangent, jac, problem, tab, cfg, state, work, out, budget):
    """Advance the integration from ``state``/``work``; see the module docstring.

    ``problem`` holds ``params``, ``atol``, ``rtol`` and ``t_eval``; ``cfg`` and
    ``state`` are one-row record arrays.  Returns ``RET_DONE`` (the run ended;
    the state's ``status`` says why), ``RET_BUFFER_FULL`` or ``RET_BUDGET``.
    """
    problem, tab, work, out = borrow(problem), borrow(tab), borrow(work), borrow(out)
    c = borrow(cfg)[0]
    s = borrow(state)[0]
    attempts = 0
    while True:
        if s["nout"] >= out.t.shape[0]:
            return RET_BUFFER_FULL
        if attempts >= budget:
            return RET_BUDGET
        if s["steps"] + s["rejected"] >= c["max_steps"]:
            return stop(ST_MAX_STEPS, work, out, s, c)
        attempts += 1
        ret = attempt(rhs, tangent, jac, problem, tab, c, s, work, out)
        if ret == RET_DONE:
            return RET_DONE


@jitable
def first_bad_derivative(K):
    """The component of the first stage whose derivative is not finite (the
    later stages inherit the NaN through their arguments), or -1."""
    for j in range(K.shape[0]):
        index = arith.first_nonfinite(K[j])
        if index >= 0:
            return index
    return -1


@jitable
def plan_step(c, s, t_eval):
    """The step to try: ``(h, h_free, clipped, target)``; ``h`` lands exactly on
    the target (the next ``t_eval`` time or the end) when it would reach or
    nearly reach it (``clipped``), ``h_free`` is the controller's choice."""
    t = s["t"]
    target = step_target(c, s, t_eval)
    direction = 1.0 if c["t_end"] > t else -1.0
    # t is t + t_lo (compensated): a step that lands on the target must cover
    # the low word too, or the tracks arrive t_lo (up to an ulp of t) late.
    remaining = (target - t) - s["t_lo"]
    h_free = s["h"]
    if abs(h_free) > c["max_step"]:
        h_free = direction * c["max_step"]
    # Land exactly on the target, and never leave a sliver below the floor.
    if abs(h_free) >= abs(remaining) or (
        abs(remaining) - abs(h_free) < FLOOR_ULPS * EPS * abs(target)
    ):
        return remaining, h_free, True, target
    return h_free, h_free, False, target


@jitable
def pair_phase(rhs, problem, tab, c, s, work, h):
    """The pair's step of size ``h`` from the current node and its error norm;
    a rejected attempt shrinks the step and returns -1."""
    s["nfev"] += steps.pair_step(rhs, s["t"], h, tab, problem.params, work)
    if not (arith.all_finite(work.V[ERR]) and arith.all_finite(work.V[CAND])):
        s["bad_component"] = first_bad_derivative(work.K)
        reject(s, h, MIN_FACTOR, 1)
        return -1.0
    V = work.V
    arith.tolerance(problem.atol, problem.rtol, V[U], V[CAND], c["relative"], c["rule"], V[DELTA])
    err = arith.weighted_norm(V[ERR], V[DELTA])
    if err > 1.0:
        reject(s, h, max(MIN_FACTOR, c["safety"] * err ** -c["error_exponent"]), 0)
        return -1.0
    return err


@jitable
def quench_phase(rhs, tangent, jac, problem, tab, c, s, work, out, h):
    """The quencher over the step, the quench decision, and the promise at the
    new node (``s["h"]`` holds the controller's free step, which a redo
    retries).  Returns 0 or 1 (the node is quenched), -1 (the attempt is
    over: rejected, or restarted from the quencher's value) or ``-1 - RET_DONE``
    (the run ends at the current node)."""
    V = work.V
    nhi, cand = V[NHI], V[CAND]
    if not (s["z_cached"] and s["cached_h"] == h):
        steps.quencher_step(rhs, tangent, jac, s["t"], h, tab, c, problem, work, s)
        if not arith.all_finite(nhi):
            s["bad_component"] = arith.first_nonfinite(nhi)
            reject(s, h, MIN_FACTOR, 1)
            return -1
        s["z_cached"] = 1
        s["cached_h"] = h
    # The global error of the candidate at the new node, against its tolerance.
    for i in range(V.shape[1]):
        V[TMP2, i] = cand[i] - nhi[i]
    arith.tolerance(problem.atol, problem.rtol, cand, cand, c["relative"], c["rule"], V[DELTA])
    quench = arith.weighted_norm(V[TMP2], V[DELTA]) > c["theta"]
    if quench and c["quench_mode"] == QUENCH_REDO and not s["redo"]:
        # Restart the same step from the quencher's value at t.
        arith.copy(V[ZHI], V[U])
        s["redo"] = 1
        s["quenches"] += 1
        s["k1_valid"] = 0
        return -1
    # The promise must hold at the new node: where the quencher can no longer
    # be trusted to within gamma_limit of the tolerance, the run ends at t,
    # the last node where it held.
    ratio = attainability(work, problem, c, nhi if quench else cand)
    if ratio > s["max_ratio"] or ratio != ratio:
        s["max_ratio"] = ratio
    if not ratio <= c["gamma_limit"]:
        s["floor_ratio"] = arith.weighted_norm(V[NFLOOR], V[DELTA])
        stop(ST_UNATTAINABLE, work, out, s, c)
        return -1 - RET_DONE
    if c["project"]:
        projected = projected_ratio(work, c, s["t"] + h)
        if projected > c["project_limit"]:
            s["projected"] = projected
            stop(ST_ABANDONED, work, out, s, c)
            return -1 - RET_DONE
    if quench:
        arith.copy(nhi, V[U])
        s["quenches"] += 1
    else:
        arith.copy(cand, V[U])
    commit_quencher(work, c, s)
    return 1 if (quench or s["redo"]) else 0


@jitable
def attempt(rhs, tangent, jac, problem, tab, c, s, work, out):
    """One step attempt; returns ``RET_DONE`` when the run ended, else -1."""
    h, h_free, clipped, target = plan_step(c, s, problem.t_eval)
    if not clipped and abs(h) < max(FLOOR_ULPS * EPS * abs(s["t"]), MIN_SUBNORMAL):
        s["failed_h"] = h
        return stop(ST_NON_FINITE if s["last_nonfinite"] else ST_UNDERFLOW, work, out, s, c)
    if not clipped:
        # The step that ends on a double: every node's time is then exact (no
        # low word), so a node reports the solution at the time it names.
        # With t + h rounded instead, the tracks arrive up to half an ulp of t
        # away from the reported time: |f| x 2.3e-13 at t = 4000, a fifth of
        # a tolerance of 1e-12 (docs/algorithm.md).
        h = (s["t"] + h) - s["t"]
    if not s["k1_valid"]:
        rhs(s["t"], work.V[U], problem.params, work.V[K1])
        s["nfev"] += 1
        if not arith.all_finite(work.V[K1]):
            s["failed_h"] = h
            s["bad_component"] = arith.first_nonfinite(work.V[K1])
            return stop(ST_NON_FINITE, work, out, s, c)
        s["k1_valid"] = 1
    # 1. The reported pair, locally extrapolated.
    err = pair_phase(rhs, problem, tab, c, s, work, h)
    if err < 0.0:
        return -1
    factor = growth_factor(c, s, err)
    if s["prev_rejected"]:
        factor = min(1.0, factor)  # no growth right after a rejection
    h_next = h * factor
    if clipped and abs(h_next) < abs(h_free):
        h_next = h_free  # a step clipped to land says nothing against the free step
    # 2.-5. The quencher, the quench, the promise.
    quenched = 0
    if c["use_z"]:
        s["h"] = h_free  # what a redo retries; an accepted step sets the next one
        quenched = quench_phase(rhs, tangent, jac, problem, tab, c, s, work, out, h)
        if quenched < 0:
            return RET_DONE if quenched == -1 - RET_DONE else -1
    else:
        arith.copy(work.V[CAND], work.V[U])
    if not clipped:
        # A step shortened to land on a target has a small error that says
        # nothing about the free step; remembered, it would hold the PI
        # controller's growth back at every t_eval time.
        s["err_prev"] = err
    return accept(c, s, work, out, problem.t_eval, h, h_next, clipped, target, quenched)


@jitable
def accept(c, s, work, out, t_eval, h, h_next, clipped, target, quenched):
    """Book-keeping of an accepted step: time, counters, the kept node, the end."""
    s["redo"] = 0
    advance_time(s, h, clipped, target)
    s["h"] = h_next
    s["steps"] += 1
    fsal = c["fsal"] and not quenched
    if fsal:
        arith.copy(work.K[work.K.shape[0] - 1], work.V[K1])
    s["k1_valid"] = 1 if fsal else 0
    s["prev_rejected"] = 0
    s["last_nonfinite"] = 0
    s["last_quenched"] = quenched
    s["last_written"] = 0
    done = clipped and target == c["t_end"]
    keep_node(c, s, work, out, t_eval, quenched, done)
    if done:
        s["status"] = ST_SUCCESS
        return RET_DONE
    return ST_RUNNING
