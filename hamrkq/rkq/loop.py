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

from hamrkq._floats import EPS
from hamrkq.rkq import arith, steps
from hamrkq.rkq.certify import (
    attainability,
    dense_attainability,
    projected_ratio,
    record_ratio,
    stored_share,
)
from hamrkq.rkq.clock import advance_time, representable_step, time_low_word
from hamrkq.rkq.jit import borrow, jitable
from hamrkq.rkq.layout import (
    CAND,
    CHECKPOINTS,
    CHK0,
    DELTA,
    ERR,
    FLOOR,
    GAM,
    GMAX,
    GNEW,
    GOLD,
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
    TMP,
    TMP2,
    UOLD,
    WHI,
    WLO,
    YMAX,
    ZHI,
    ZLO,
    ZOLD,
    ZOLDLO,
    U,
    checkpoint_fraction,
)
from hamrkq.rkq.start import FLOOR_ULPS, begin, write_node, write_rounding

# Step-size control (Hairer, Norsett & Wanner, Solving ODEs I, II.4).
MIN_FACTOR = 0.2  # never shrink by more than 5x on one rejection
MAX_FACTOR = 5.0  # never grow by more than 5x on one acceptance
#: A rejected step shrinks by at least this factor: with ``safety=1`` (the
#: top of its range) the factor ``safety err^(-1/q)`` tends to 1 as ``err``
#: falls to 1, and the RK3(4) pair stalled at Kepler's pericentre (e = 0.9,
#: atol 1e-6: 19 825 rejections after 175 steps, tests/test_rkq_core.py;
#: QA's rk34q10 at 1e-8: 2 999 405 after 595).  Below the default
#: safety 0.9 the factor is already smaller: nothing changes there.
MAX_REJECT_FACTOR = 0.9
#: :func:`quench_phase`'s "the run ends at the current node", apart from its
#: -1, "this attempt is over" (it was ``-1 - RET_DONE``, which with
#: ``RET_DONE = 0`` is -1 too: every rejected or redone attempt ended the
#: kernel's call as if the run had, which the driver's loop absorbed and the
#: SciPy solver, stepping once, took for the end: ``quench="redo"`` raised
#: KeyError there).
RUN_ENDS = -2


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
    # A run's first call starts it (nothing evaluated yet: the SciPy solver
    # and the batch loop start their runs themselves), here rather than in
    # the driver, where begin ran interpreted (about 20 us of a tiny
    # problem's call; benchmarks/per_call.py).
    if s["nfev"] == 0 and begin(rhs, problem, c, s, work, out) != ST_RUNNING:
        return RET_DONE
    attempts = 0
    while True:
        if s["dense_pending"]:
            emitted = emit_dense(rhs, problem, tab, c, s, work, out)
            if emitted == RET_BUFFER_FULL:
                return RET_BUFFER_FULL
            if emitted == RET_DONE or s["status"] == ST_SUCCESS:
                return RET_DONE
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
def reaches(h, remaining, target):
    """Whether a step ``h`` reaches ``target``, ``remaining`` away, or would
    leave a sliver below the floor before it."""
    return abs(h) >= abs(remaining) or (abs(remaining) - abs(h) < FLOOR_ULPS * EPS * abs(target))


@jitable
def plan_step(c, s, t_eval):
    """The step to try: ``(h, h_free, clipped, target, dense)``; ``h`` lands
    exactly on the target (the next ``t_eval`` time or the end) when it would
    reach or nearly reach it (``clipped``), ``h_free`` is the controller's
    choice.  A ``t_eval`` time within ``dense_share`` of the free step
    (:data:`hamrkq.rkq.config.DENSE_SHARE`) is passed, not landed on
    (``dense``: the step's ``t_eval`` times are written from dense output,
    :func:`emit_dense`), where there is a quencher track to step from."""
    t = s["t"]
    target = step_target(c, s, t_eval)
    direction = 1.0 if c["t_end"] > t else -1.0
    # t is t + t_lo (compensated): a step that lands on the target must cover
    # the low word too, or the tracks arrive t_lo (up to an ulp of t) late.
    remaining = (target - t) - s["t_lo"]
    h_free = s["h"]
    if abs(h_free) > c["max_step"]:
        h_free = direction * c["max_step"]
    if not reaches(h_free, remaining, target):
        return representable_step(t, s["t_lo"], h_free), h_free, False, target, False
    floor = FLOOR_ULPS * EPS * abs(target)
    if abs(h_free) < abs(remaining) and abs(remaining) >= 2.0 * floor:
        # The free step would leave a sliver below the floor before the
        # target: half the way, not a step stretched to land, which the
        # controller's rejections could not shrink (at t = 1e12 the floor is
        # 2.2e-3, a quarter of the oscillator's steps at 1e-10: the stretched
        # step was rejected 19 869 times).
        half = representable_step(t, s["t_lo"], 0.5 * remaining)
        return half, h_free, False, target, False
    if c["use_z"] and target != c["t_end"] and abs(remaining) < c["dense_share"] * abs(h_free):
        end = c["t_end"]
        to_end = (end - t) - s["t_lo"]
        if reaches(h_free, to_end, end):
            return to_end, h_free, True, end, True
        return representable_step(t, s["t_lo"], h_free), h_free, False, target, True
    # Land exactly on the target.
    return remaining, h_free, True, target, False


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
        factor = c["safety"] * err ** -c["error_exponent"]
        reject(s, h, min(MAX_REJECT_FACTOR, max(MIN_FACTOR, factor)), 0)
        return -1.0
    return err


@jitable
def quench_phase(rhs, tangent, jac, problem, tab, c, s, work, out, h):
    """The quencher over the step, the quench decision, and the promise at the
    new node (``s["h"]`` holds the controller's free step, which a redo
    retries).  Returns 0 or 1 (the node is quenched), -1 (the attempt is
    over: rejected, or restarted from the quencher's value) or
    :data:`RUN_ENDS` (the run ends at the current node)."""
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
    unew = nhi if quench else cand
    t_lo = time_low_word(s, h)
    ratio = attainability(work, problem, c, unew, t_lo, h)
    if not record_ratio(s, c, ratio, V[NFLOOR], V[DELTA]):
        stop(ST_UNATTAINABLE, work, out, s, c)
        return RUN_ENDS
    if c["project"]:
        projected = projected_ratio(work, c, s["t"] + h)
        if projected > c["project_limit"]:
            s["projected"] = projected
            stop(ST_ABANDONED, work, out, s, c)
            return RUN_ENDS
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
    h, h_free, clipped, target, dense = plan_step(c, s, problem.t_eval)
    floor = max(FLOOR_ULPS * EPS * abs(s["t"]), MIN_SUBNORMAL)
    # A step clipped to land is below the floor where the controller asks
    # for less than it and less than the floor: a span shorter than the floor
    # at t = 1e15 retried its landing step a million times.
    if (abs(h_free) < min(abs(h), floor)) if clipped else (abs(h) < floor):
        s["failed_h"] = h_free if clipped else h
        return stop(ST_NON_FINITE if s["last_nonfinite"] else ST_UNDERFLOW, work, out, s, c)
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
    if factor <= 1.0:
        # The first steps' growth from the first step is over: the free
        # steps' range (step_range) is measured from here.
        s["ramped"] = 1
    if s["prev_rejected"]:
        factor = min(1.0, factor)  # no growth right after a rejection
    h_next = h * factor
    if clipped and abs(h_next) < abs(h_free):
        h_next = h_free  # a step clipped to land says nothing against the free step
    # 2.-5. The quencher, the quench, the promise.
    quenched = 0
    if dense:
        keep_old_node(s, work)
    if c["use_z"]:
        s["h"] = h_free  # what a redo retries; an accepted step sets the next one
        quenched = quench_phase(rhs, tangent, jac, problem, tab, c, s, work, out, h)
        if quenched < 0:
            return RET_DONE if quenched == RUN_ENDS else -1
    else:
        arith.copy(work.V[CAND], work.V[U])
    if not clipped:
        # A step shortened to land on a target has a small error that says
        # nothing about the free step; remembered, it would hold the PI
        # controller's growth back at every t_eval time.
        s["err_prev"] = err
    return accept(c, s, work, out, problem.t_eval, h, h_next, clipped, target, quenched, dense)


@jitable
def accept(c, s, work, out, t_eval, h, h_next, clipped, target, quenched, dense):  # noqa: PLR0913
    """Book-keeping of an accepted step: time, counters, the kept node, the end."""
    s["redo"] = 0
    advance_time(s, h, clipped, target)
    track_maxima(c, s, work)
    if s["ramped"] and not clipped:
        s["h_least"] = min(s["h_least"], abs(h))
        s["h_most"] = max(s["h_most"], abs(h))
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
    if dense:
        # The t_eval times inside the step, then the node, then the end:
        # written by emit_dense, which may wait for room in the buffer.
        s["dense_pending"] = 1
        return ST_RUNNING
    keep_node(c, s, work, out, t_eval, quenched, done)
    if done:
        s["status"] = ST_SUCCESS
        return RET_DONE
    return ST_RUNNING


@jitable
def step_range(s):
    """The ratio of the largest free step a run accepted to its smallest,
    from the first step after which the controller asked for no growth (the
    first steps grow from a first step of 1e-6 to 1e-3 of the orbit's); 1
    before any (a run of steps clipped to land, or still growing)."""
    if not s["h_least"] > 0.0 or s["h_most"] < s["h_least"]:
        return 1.0
    return s["h_most"] / s["h_least"]


@jitable
def track_maxima(c, s, work):
    """Fold the new node into ``V[YMAX]`` and ``V[GMAX]``, after keeping
    ``V[GMAX]`` as it was before it in the rows of the checkpoints the step
    passed: the largest ``|Gamma|`` up to the fraction ``2^-j`` of the
    interval is the largest over the nodes at or before it."""
    V = work.V
    reached = (s["t"] - c["t_start"]) / (c["t_end"] - c["t_start"])
    while s["checkpoint"] < CHECKPOINTS and reached > checkpoint_fraction(s["checkpoint"]):
        arith.copy(V[GMAX], V[CHK0 + s["checkpoint"]])
        s["checkpoint"] += 1
    for i in range(V.shape[1]):
        V[YMAX, i] = arith.fmax(V[YMAX, i], abs(V[U, i]))
        V[GMAX, i] = arith.fmax(V[GMAX, i], abs(V[GAM, i]))


@jitable
def keep_old_node(s, work):
    """Keep the node a step starts from (its reported solution, quencher
    track and Gamma), which the dense ``t_eval`` values inside the step
    interpolate from."""
    V = work.V
    for new, old in ((U, UOLD), (ZHI, ZOLD), (ZLO, ZOLDLO), (GAM, GOLD)):
        arith.copy(V[new], V[old])
    s["t_old"] = s["t"]
    s["t_old_lo"] = s["t_lo"]


@jitable
def emit_dense(rhs, problem, tab, c, s, work, out):
    """Write the ``t_eval`` times strictly inside the last step from dense
    output (:func:`write_dense`), then the step's own node if it is a
    ``t_eval`` time, and end the run if the step did; ``RET_BUFFER_FULL``
    when the buffer fills first (the rest is written on the next call)."""
    t_eval = problem.t_eval
    forward = s["t"] > s["t_old"]
    while s["eval_index"] < t_eval.shape[0]:
        p = t_eval[s["eval_index"]]
        if not ((p < s["t"]) if forward else (p > s["t"])):
            break
        if s["nout"] >= out.t.shape[0]:
            return RET_BUFFER_FULL
        if not write_dense(rhs, problem, tab, c, s, work, out, p):
            return RET_DONE
        s["eval_index"] += 1
    if s["nout"] >= out.t.shape[0]:
        return RET_BUFFER_FULL
    s["dense_pending"] = 0
    done = s["t"] == c["t_end"]  # a step that reaches the end lands on it exactly
    keep_node(c, s, work, out, t_eval, s["last_quenched"], done)
    if done:
        s["status"] = ST_SUCCESS
    return ST_RUNNING


@jitable
def write_dense(rhs, problem, tab, c, s, work, out, p):
    """Append the solution at ``p``, inside the last step, as
    :func:`hamrkq.rkq.dense.evaluate` gives it between two nodes
    (:func:`hamrkq.rkq.steps.dense_value`): one quencher step from the
    quencher track at the nearer node, plus the reported solution's
    difference to that track interpolated linearly (or not, where it exceeds
    the tolerance there: the value is then quenched); the quencher's value
    and Gamma (interpolated) beside it."""
    V = work.V
    w = (p - s["t_old"]) / (s["t"] - s["t_old"])
    if abs(p - s["t_old"]) <= abs(s["t"] - p):
        start, start_lo, t_start, t_start_lo = ZOLD, ZOLDLO, s["t_old"], s["t_old_lo"]
    else:
        start, start_lo, t_start, t_start_lo = ZHI, ZLO, s["t"], s["t_lo"]
    gap = V[TMP]
    for i in range(V.shape[1]):
        gap[i] = (1.0 - w) * (V[UOLD, i] - V[ZOLD, i]) + w * (V[U, i] - V[ZHI, i])
    n = s["nout"]
    # from t_start + t_start_lo (compensated time) to exactly p
    h = (p - t_start) - t_start_lo
    substeps = steps.dense_substeps(h, s["t"] - s["t_old"], c["z_substeps"])
    evaluations, quenched = steps.dense_value(
        rhs, t_start, V[start], V[start_lo], h, substeps, tab, problem.params, gap,
        problem.atol, problem.rtol, c["relative"], c["rule"], c["theta"], work, out.y[n],
        out.z[n],
    )  # fmt: skip
    s["nfev"] += evaluations
    out.t[n] = p
    for i in range(V.shape[1]):
        out.gamma[n, i] = (1.0 - w) * V[GOLD, i] + w * V[GAM, i]
    out.quenched[n] = 1 if quenched else 0
    write_rounding(work, out.rounding[n])
    ratio = dense_attainability(work, out.z[n], out.gamma[n])
    if not record_ratio(s, c, ratio, V[FLOOR], V[DELTA]):
        # The promise cannot be kept at p: the run ends before it, reported
        # where it failed (the step's node, beyond p, is not returned).
        s["stored_ratio"] = stored_share(work, out.z[n])
        s["t"] = p
        s["t_lo"] = 0.0
        s["status"] = ST_UNATTAINABLE
        return False
    s["nout"] = n + 1
    return True
