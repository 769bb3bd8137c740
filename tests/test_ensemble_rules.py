"""The ensemble's rules over members, in whole-array operations, decide as
``solve``'s rules for one run decide, member by member.

``hamrkq.ensemble.chunk`` decides for every member of a chunk at once what
its ``y0`` decides of the options (auto's member, whether the rounding
witness runs) and, after the batch loop, which members ``solve`` alone would
not return as they are (a saturated shadow, a rerun with the witness).  The
per-member functions in hamrkq.rkq and hamrkq.solve are the definition:
here the ``*_per_row`` functions are checked against them row by row on
states chosen so that the decisions differ, and ensembles whose members
differ in each decision against ``solve`` alone.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_ensemble import _assert_member_equals_solve

import hamrkq
from hamrkq.rkq import auto_rules as ar
from hamrkq.rkq import witness_rules as wr

M, D = 600, 4


def _states(seed: int) -> np.ndarray:
    """``M`` states of ``D`` components from 1e-3 to 1e3 in size, of either
    sign, some components zero and some halves all zero (the scales' cases)."""
    rng = np.random.default_rng(seed)
    states = rng.choice([-1.0, 1.0], (M, D)) * 10.0 ** rng.uniform(-3, 3, (M, D))
    states[rng.random((M, D)) < 0.1] = 0.0
    states[: M // 20, : D // 2] = 0.0
    states[M // 20 : M // 10, D // 2 :] = 0.0
    states[-3:] = 0.0
    return states


#: (atol, rtol) pairs: one atol for every component, with and without rtol,
#: and per-component floors (the outer solar system's kind), whose scales
#: share out each half.
TOLERANCES = [
    (np.full(D, 1e-7), np.zeros(D)),
    (np.full(D, 1e-9), np.full(D, 1e-6)),
    (np.array([1e-7, 1e-8, 1e-6, 1e-9]), np.full(D, 1e-8)),
]


def _mixed(decisions: np.ndarray) -> np.ndarray:
    """``decisions``, checked to differ between rows (or the test proves nothing)."""
    assert decisions.any() and not decisions.all()
    return decisions


@pytest.mark.parametrize("atol, rtol", TOLERANCES)
def test_the_witness_rules_per_row_decide_as_for_each_state_alone(atol, rtol):
    states = _states(1)
    rng = np.random.default_rng(2)
    sizes = np.abs(states) * 10.0 ** rng.uniform(0, 3, (M, D))
    steps = (10.0 ** rng.uniform(1, 4.5, M)).astype(np.int64)
    ranges = 10.0 ** rng.uniform(0, 1.5, M)
    np.testing.assert_array_equal(
        wr.component_scales(atol, states), [wr.component_scales(atol, y) for y in states]
    )
    for substeps in (1, 4, 5):
        for time_scale in (0.0, 1e4):
            rows = wr.needs_witness_per_row(
                atol, rtol, states, substeps=substeps, time_scale=time_scale
            )
            alone = [wr.needs_witness(atol, rtol, y, False, substeps, time_scale) for y in states]
            np.testing.assert_array_equal(rows, alone)
            if substeps < wr.WITNESS_SUBSTEPS:
                _mixed(rows)
        rows = wr.time_rounding_matters_per_row(atol, rtol, states, 1e4)
        alone = [wr.time_rounding_matters(atol, rtol, y, 1e4) for y in states]
        np.testing.assert_array_equal(_mixed(rows), alone)
    assert wr.needs_witness_per_row(atol, rtol, states, stage_rounding=True).all()
    rows = wr.needs_witness_after_run_per_row(atol, rtol, states, steps, sizes, ranges)
    alone = [
        wr.needs_witness_after_run(atol, rtol, y, int(n), s, float(r))
        for y, n, s, r in zip(states, steps, sizes, ranges, strict=True)
    ]
    np.testing.assert_array_equal(_mixed(rows), alone)
    rows = wr.state_outgrew_its_start_per_row(atol, rtol, states, sizes)
    alone = [
        wr.state_outgrew_its_start(atol, rtol, y, s) for y, s in zip(states, sizes, strict=True)
    ]
    np.testing.assert_array_equal(_mixed(rows), alone)


@pytest.mark.parametrize("atol, rtol", [(np.full(D, 2e-7), np.zeros(D)), *TOLERANCES])
def test_auto_s_member_per_row_is_the_member_of_each_state_alone(atol, rtol):
    states = _states(3)
    tolerances = ar.auto_tolerance_per_row(atol, rtol, states)
    np.testing.assert_array_equal(tolerances, [ar.auto_tolerance(atol, rtol, y) for y in states])
    for dim in (D, ar.AUTO_LARGE_DIM):
        names = ar.auto_member_per_row(dim, tolerances)
        np.testing.assert_array_equal(names, [ar.auto_member(dim, t)[0] for t in tolerances])
    if atol[0] == 2e-7:  # loose where the state's size is at most 2
        assert set(ar.auto_member_per_row(D, tolerances)) == {ar.AUTO_MEMBER, ar.AUTO_LARGE_MEMBER}


def test_the_growth_of_maxima_per_row_reads_each_row_as_alone():
    rng = np.random.default_rng(4)
    to_middle = 10.0 ** rng.uniform(-12, -8, (M, D))
    to_end = to_middle * 10.0 ** rng.uniform(0, 3, (M, D))
    to_middle[:50] = 0.0  # no estimate up to the middle
    to_end[:25] = 0.0  # nor at the end
    to_middle[50:60, 0] = np.inf
    to_end[60:70, 1] = np.nan
    delta = 10.0 ** rng.uniform(-10, -6, (M, D))
    rows = ar.growth_of_maxima_per_row(to_middle, to_end, delta)
    alone = [
        ar.growth_of_maxima(a, b, c) for a, b, c in zip(to_middle, to_end, delta, strict=True)
    ]
    np.testing.assert_array_equal(rows, alone)
    # what growth_of_maxima's docstring says: no estimate anywhere, no growth;
    # an estimate at the end only, or one that is not finite, an infinite one
    assert (rows[:25] == 1.0).all() and (rows[25:70] == math.inf).all()
    ratio = np.max(to_end[70:] / delta[70:], axis=1) / np.max(to_middle[70:] / delta[70:], axis=1)
    np.testing.assert_array_equal(rows[70:], ratio)


def _runs_again_alone_member_by_member(batch, task, request):
    """What hamrkq.ensemble.chunk._runs_again_alone decided before it
    decided over members at once: the per-member rules of hamrkq.solve, one
    member at a time (with why: saturated, and rerun with the witness)."""
    from hamrkq.rkq.auto_rules import SHADOW_SATURATION
    from hamrkq.solve.auto import (
        MIN_GROWTH_STEPS,
        folded_growth,
        reruns_with_witness,
        witness_rerun_needed,
    )
    from hamrkq.solve.shadow import shadow_departures

    m = batch.status.shape[0]
    saturated, rerun = np.zeros(m, dtype=bool), np.zeros(m, dtype=bool)
    for i in np.flatnonzero(batch.status == hamrkq.Status.SUCCESS.code):
        departure = shadow_departures(task, batch.gamma_to_end[i : i + 1], batch.y_size[i])
        saturated[i] = departure is not None and departure[0] > SHADOW_SATURATION
        if not reruns_with_witness(task):
            continue
        steps = int(batch.stats[i, 0])
        nodes = request.times.size if task.t_eval is not None else steps + 1
        factor = 1.0
        if steps >= MIN_GROWTH_STEPS and nodes >= 3:
            y_size = batch.y_size[i]
            factor = folded_growth(task, batch.gamma_to_middle[i], batch.gamma_to_end[i], y_size)
        rerun[i] = witness_rerun_needed(
            task, request.y0[i], batch.y_size[i], factor, steps, float(batch.step_range[i])
        )
    return saturated, rerun


def _spy_on_the_batch(monkeypatch):
    """Record each batch's decisions: the chunk's, and member by member."""
    from hamrkq.ensemble import chunk

    decided, real = [], chunk._runs_again_alone

    def spy(batch, task, request):
        again = real(batch, task, request)
        decided.append((again, *_runs_again_alone_member_by_member(batch, task, request)))
        return again

    monkeypatch.setattr(chunk, "_runs_again_alone", spy)
    return decided


@pytest.mark.parametrize(
    "name, spans, scales, options",
    [
        # FPU chain at 1e-3 with four quencher steps to t = 200: the shadow of
        # the larger amplitudes saturates (1.27 and 1.50 of the orbit's size),
        # the first's estimate also grew 132-fold; the smaller ones neither
        ("fpu", 1, [1.0, 0.999, 0.5, 0.7], {"method": "rk67q9", "z_substeps": 4, "atol": 1e-3}),
        # Arenstorf over three periods: the first two grew exponentially
        # (66 538- and 865-fold) without saturating, the others 2.2- and
        # 1.5-fold (the regular rule: not long enough for the witness)
        ("arenstorf", 3, [1.0, 1 + 1e-9, 0.9, 1.1], {"method": "rk45q12", "atol": 1e-8}),
    ],
)
def test_members_that_run_again_alone_are_those_solve_alone_would_not_return(
    monkeypatch, name, spans, scales, options
):
    decided = _spy_on_the_batch(monkeypatch)
    problem = hamrkq.load_problem(name)
    options = {"t_span": (0.0, spans * problem.t_span[1]), **options}
    scales = np.array(scales)[:, None]
    ens = hamrkq.ensemble(problem, q0=problem.q0 * scales, p0=problem.p0 * scales, workers=1,
                          chunk_size=len(scales), **options)  # fmt: skip
    ((again, saturated, rerun),) = decided
    np.testing.assert_array_equal(again, saturated | rerun)
    if name == "fpu":
        np.testing.assert_array_equal(saturated, [True, True, False, False])
        assert rerun[0] and not rerun[2:].any()
    else:
        np.testing.assert_array_equal(rerun, [True, True, False, False])
        assert not saturated.any()
    for i in range(len(scales)):
        _assert_member_equals_solve(ens, i, problem, **options)


def test_members_whose_y0_decide_differently_group_as_each_alone_decides():
    """Pendulum members at atol 1e-12, rtol 1e-6: auto runs rk67q9 where
    every component's tolerance is at least 1e-7 (|q|, |p| >= 0.1), rk78q12
    elsewhere, and the witness where a component is 0 (its tolerance 1e-12,
    below 3e-10 of its half's size); each group is batched, and every member
    equals solve alone."""
    from hamrkq.ensemble import chunk
    from hamrkq.ensemble.request import build_request
    from hamrkq.rkq.auto_rules import auto_member, auto_tolerance
    from hamrkq.rkq.witness_rules import needs_witness
    from hamrkq.solve.dispatch import member_of, time_scale

    pend = hamrkq.load_problem("pendulum")
    q0 = np.array([[0.5], [0.05], [0.0], [0.5], [-0.3], [0.0], [2.0]])
    p0 = np.array([[0.5], [0.5], [0.5], [0.0], [0.2], [0.0], [0.01]])
    options = {"method": "auto", "atol": 1e-12, "rtol": 1e-6}
    request = build_request(pend, q0, p0, (0, 0.5), None, None, options)
    prepared = chunk._batch_prepared(request)
    auto, witness = chunk.decided_by_y0(prepared, request.ham.dim, request.y0)
    task, member = prepared.task, member_of(prepared.task)
    for i, y0 in enumerate(request.y0):
        assert auto[i] == auto_member(2, auto_tolerance(task.atol, task.rtol, y0))[0]
        assert witness[i] == needs_witness(task.atol, task.rtol, y0,
                                           member.stage_rounding_dominates,
                                           member.z_substeps, time_scale(task))  # fmt: skip
    assert list(auto) == ["rk67q9", "rk78q12", "rk78q12", "rk78q12", "rk67q9", "rk78q12",
                          "rk78q12"]  # fmt: skip
    assert list(witness) == [False, False, True, True, False, True, False]
    groups = chunk.batch_groups(request, prepared)
    assert [list(g) for g in groups] == [[0, 4], [1, 6], [2, 3, 5]]
    ens = hamrkq.ensemble(
        pend, q0=q0, p0=p0, t_span=(0, 0.5), workers=1, chunk_size=len(q0), **options
    )
    for i in range(len(q0)):
        sol = _assert_member_equals_solve(ens, i, pend, t_span=(0, 0.5), **options)
        assert sol.method == auto[i]
        assert sol.options["rounding_witness"] == witness[i]


@pytest.mark.parametrize("method", ["rk78q12", "rk34q8"])
def test_the_rules_after_a_run_per_row_decide_as_solve_s_for_each_run(method):
    """hamrkq.solve.member_rules against hamrkq.solve.auto's per-run rules,
    row by row and for one run alone: the shadow estimate (exponential
    growth, the length and the state's size) and the tangent estimate (a
    state grown beyond its start)."""
    from hamrkq.solve import auto, member_rules, prepare

    problem = hamrkq.load_problem("henon_heiles")
    task = prepare(problem, q0=[0.1, 0.2], p0=[0.3, 0.0], method=method, atol=1e-8).task
    assert auto.reruns_with_witness(task)
    rng = np.random.default_rng(5)
    states = rng.uniform(-0.3, 0.3, (M, D))
    states[:20, 0] = 0.0
    sizes = np.abs(states) * 10.0 ** rng.uniform(0, 2.5, (M, D))
    to_middle = 1e-9 * 10.0 ** rng.uniform(-4, 0, (M, D))
    to_end = to_middle * 10.0 ** rng.uniform(0, 3, (M, D))
    to_middle[:10] = 0.0
    steps = (10.0 ** rng.uniform(1, 5, M)).astype(np.int64)
    ranges = 10.0 ** rng.uniform(0, 1.5, M)
    growth = member_rules.folded_growth_per_row(task, to_middle, to_end, sizes)
    rerun = member_rules.witness_rerun_needed_per_row(task, states, sizes, growth, steps, ranges)
    _mixed(growth > ar.EXPONENTIAL_GROWTH)
    _mixed(rerun)
    for i in range(M):
        factor = auto.folded_growth(task, to_middle[i], to_end[i], sizes[i])
        assert growth[i] == factor
        assert (
            member_rules.folded_growth_per_row(task, to_middle[i], to_end[i], sizes[i]) == factor
        )
        one = (task, states[i], sizes[i], factor, int(steps[i]), float(ranges[i]))
        assert rerun[i] == auto.witness_rerun_needed(*one)
        assert member_rules.witness_rerun_needed_per_row(*one) == rerun[i]
