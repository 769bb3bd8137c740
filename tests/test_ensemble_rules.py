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
from hamrkq.rkq import scales
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


#: The rules after a run by hand, on states of four components (q1, q2, p1,
#: p2; the scales are measured per half): (y0, the run's largest |y_k|,
#: atol, rtol, steps, step range), whether the witness is needed after the
#: run (``needs_witness_after_run``) and whether the state outgrew its start
#: (``state_outgrew_its_start``, at the reference steps and a range of 1).
#: The threshold is WITNESS_BELOW = 3e-10 times each half's largest size,
#: times length_factor(N) = max(sqrt(N / 1e4), (N / 15 000)^2) (1 at 10 000
#: steps) and close_approach_factor(r) = max(1, r / 2).
ONES = [1.0, 1.0, 1.0, 1.0]
AFTER_A_RUN = [
    # 3e-10 against atol 1e-9: neither
    ((ONES, ONES, 1e-9, 0.0, 10_000, 1.0), False, False),
    # (40 000 / 15 000)^2 = 7.1: 2.1e-9 above 1e-9
    ((ONES, ONES, 1e-9, 0.0, 40_000, 1.0), True, False),
    # a step range of 8: 4 times, 1.2e-9; of 6: 3 times, 9e-10
    ((ONES, ONES, 1e-9, 0.0, 10_000, 8.0), True, False),
    ((ONES, ONES, 1e-9, 0.0, 10_000, 6.0), False, False),
    # q1 reached 5: 1.5e-9; grew 5-fold, not more than 10
    ((ONES, [5.0, 1.0, 1.0, 1.0], 1e-9, 0.0, 10_000, 1.0), True, False),
    # q1 reached 11: 3.3e-9, where the start's 3e-10 was above 1e-9
    ((ONES, [11.0, 1.0, 1.0, 1.0], 1e-9, 0.0, 10_000, 1.0), True, True),
    # exactly 10-fold is not more
    ((ONES, [10.0, 1.0, 1.0, 1.0], 1e-9, 0.0, 10_000, 1.0), True, False),
    # 11-fold, but 3.3e-9 is below atol 1e-8
    ((ONES, [11.0, 1.0, 1.0, 1.0], 1e-8, 0.0, 10_000, 1.0), False, False),
    # 100-fold at 1e-11: the rule at the start (3e-10) called for it already
    ((ONES, [100.0, 1.0, 1.0, 1.0], 1e-11, 0.0, 10_000, 1.0), True, False),
    # both q zero at the start: measured by the whole state (2); q1 reached
    # 30, 15-fold: 9e-9 against 6e-10 at the start
    (([0.0, 0.0, 2.0, 2.0], [30.0, 0.0, 2.0, 2.0], 1e-9, 0.0, 10_000, 1.0), True, True),
    # rtol: q2 = 0 has atol alone, 1e-12, below 3e-10 of 2
    (([2.0, 0.0, 1.0, 1.0], [2.0, 0.0, 1.0, 1.0], 1e-12, 1e-9, 10_000, 1.0), True, False),
    # rtol 1e-9 and atol 1e-9: 2e-9 and 1e-9 against 6e-10 and 3e-10
    (([2.0, 0.0, 1.0, 1.0], [2.0, 0.0, 1.0, 1.0], 1e-9, 1e-9, 10_000, 1.0), False, False),
    # per-component floors share out the half: q2's scale is 1e-10 / 1e-8 of
    # q1's 1, 0.01, at the start; it reached 0.5 (50-fold), where 1.5e-10 is
    # above its atol 1e-10 (3e-12 at the start)
    (
        (
            [1.0, 0.001, 1.0, 1.0],
            [1.0, 0.5, 1.0, 1.0],
            [1e-8, 1e-10, 1e-8, 1e-8],
            0.0,
            10_000,
            1.0,
        ),
        True,
        True,
    ),
    # a size that is NaN did not grow, and has no threshold
    ((ONES, [np.nan, 1.0, 1.0, 1.0], 1e-9, 0.0, 10_000, 1.0), False, False),
]


def _after_a_run_rows():
    """:data:`AFTER_A_RUN` as the per-row rules take it: atol and rtol per
    component, one row per case."""
    columns = list(zip(*(case for case, _, _ in AFTER_A_RUN), strict=True))
    y0, sizes, steps, ranges = (np.array(columns[k], dtype=float) for k in (0, 1, 4, 5))
    atol, rtol = (np.array([np.broadcast_to(v, (D,)) for v in columns[k]]) for k in (2, 3))
    after = np.array([expected for _, expected, _ in AFTER_A_RUN])
    outgrew = np.array([expected for _, _, expected in AFTER_A_RUN])
    return y0, sizes, atol, rtol, steps.astype(np.int64), ranges, after, outgrew


def test_the_rules_after_a_run_per_row_give_the_hand_computed_decisions():
    y0, sizes, atol, rtol, steps, ranges, after, outgrew = _after_a_run_rows()
    for k in range(len(AFTER_A_RUN)):  # (each case's own atol and rtol)
        rows = y0[k : k + 1], steps[k : k + 1], sizes[k : k + 1], ranges[k : k + 1]
        decided = wr.needs_witness_after_run_per_row(atol[k], rtol[k], *rows)
        assert decided.tolist() == [after[k]], AFTER_A_RUN[k]
        if steps[k] == wr.WITNESS_REFERENCE_STEPS and ranges[k] == 1.0:
            grown = wr.state_outgrew_its_start_per_row(
                atol[k], rtol[k], y0[k : k + 1], sizes[k : k + 1]
            )
            assert grown.tolist() == [outgrew[k]], AFTER_A_RUN[k]
    # one atol and rtol for every row: the first seven cases at once
    rows = slice(0, 7)
    assert (atol[rows] == 1e-9).all() and (rtol[rows] == 0.0).all()
    decided = wr.needs_witness_after_run_per_row(
        atol[0], rtol[0], y0[rows], steps[rows], sizes[rows], ranges[rows]
    )
    np.testing.assert_array_equal(decided, after[rows])


@pytest.mark.parametrize("substeps", [1, 4, 5])
def test_the_witness_rules_at_the_start_per_row_give_the_hand_computed_decisions(substeps):
    """Below 3e-10 of the state's size (3e-8 with four quencher steps, every
    tolerance with five); with a time scale, below 1000 eps |t| (2.2e-9 at
    |t| = 1e4)."""
    states = np.array([ONES, [2.0, 0.0, 0.5, 0.5], [0.0, 0.0, 0.0, 0.0]])
    by_atol = {
        # atol: (tolerance below the rule's threshold at each state)
        1e-10: [True, True, True],  # 1e-10 < 3e-10 (of 1, of 2 and 0.5, of 1)
        5e-10: [False, True, False],  # 5e-10 < 6e-10 (q of size 2) only
        1e-8: [False, False, False],
    }
    for atol, below in by_atol.items():
        rows = wr.needs_witness_per_row(np.full(D, atol), np.zeros(D), states, substeps=substeps)
        if substeps >= wr.WITNESS_SUBSTEPS:
            expected = [True] * 3
        elif substeps >= wr.WITNESS_SUBSTEPS_NEAR_FLOOR:  # 3e-8: every atol here
            expected = [True] * 3
        else:
            expected = below
        assert rows.tolist() == expected, atol
    for atol, expected in ((1e-9, [True, True, True]), (1e-8, [False, False, False])):
        rows = wr.time_rounding_matters_per_row(np.full(D, atol), np.zeros(D), states, 1e4)
        assert rows.tolist() == expected
    assert not wr.time_rounding_matters_per_row(np.full(D, 1e-15), np.zeros(D), states, 0.0).any()
    assert wr.needs_witness_per_row(1e-3, 0.0, states, stage_rounding=True).all()


def test_the_scales_and_auto_s_tolerance_per_row_are_the_hand_computed_values():
    states = np.array(
        [[1.0, 0.001, 1.0, 1.0], [0.0, 0.0, 2.0, 3.0], [0.0] * 4, [3.0, -4.0, 0.0, 0.0]]
    )
    np.testing.assert_array_equal(
        scales.component_scales(1e-8, states),
        [[1.0, 1.0, 1.0, 1.0], [3.0, 3.0, 3.0, 3.0], [1.0] * 4, [4.0, 4.0, 4.0, 4.0]],
    )
    # floors share out each half: q2's 1e-10 is 0.01 of q1's 1e-8
    np.testing.assert_array_equal(
        scales.component_scales([1e-8, 1e-10, 1e-8, 1e-8], states[:1]), [[1.0, 0.01, 1.0, 1.0]]
    )
    # min_k max(atol, rtol |y_k|) over max(1, max_k |y_k|)
    states = np.array([[2.0, 0.0, 0.5, 0.0], [25.0, 0.0, 0.0, 0.0], [0.0] * 4])
    tolerances = ar.auto_tolerance_per_row(1e-9, 1e-6, states)
    np.testing.assert_allclose(tolerances, [1e-9 / 2, 1e-9 / 25, 1e-9], rtol=1e-15)
    tolerances = ar.auto_tolerance_per_row(np.full(D, 1e-7), np.zeros(D), states)
    np.testing.assert_allclose(tolerances, [1e-7 / 2, 1e-7 / 25, 1e-7], rtol=1e-15)
    # rk67q9 at 1e-7 or looser, or from 12 state variables on
    assert ar.auto_member_per_row(D, tolerances).tolist() == ["rk78q12", "rk78q12", "rk67q9"]
    assert set(ar.auto_member_per_row(ar.AUTO_LARGE_DIM, tolerances)) == {"rk67q9"}


@pytest.mark.parametrize("atol, rtol", TOLERANCES)
def test_the_rules_on_python_floats_are_the_whole_array_rules(atol, rtol):
    """One small state's rules are computed on Python floats
    (``scales.SMALL_STATE``), an ensemble's rows in whole-array
    operations: two computations, the same bits, on states chosen so that
    the decisions differ."""
    assert D <= scales.SMALL_STATE
    states = _states(1)
    rng = np.random.default_rng(2)
    sizes = np.abs(states) * 10.0 ** rng.uniform(0, 3, (M, D))
    steps = (10.0 ** rng.uniform(1, 4.5, M)).astype(np.int64)
    ranges = 10.0 ** rng.uniform(0, 1.5, M)
    early = 10.0 ** rng.uniform(0, 5, M)  # beyond t^2 (256) in about half the rows
    early[:20] = np.inf  # no reading that early: no amplification
    np.testing.assert_array_equal(
        scales.component_scales(atol, states), [scales.component_scales(atol, y) for y in states]
    )
    rows = wr.needs_witness_after_run_per_row(atol, rtol, states, steps, sizes, ranges, early)
    alone = [
        wr.needs_witness_after_run(atol, rtol, y, int(n), s, float(r), float(g))
        for y, n, s, r, g in zip(states, steps, sizes, ranges, early, strict=True)
    ]
    np.testing.assert_array_equal(_mixed(rows), alone)
    rows = wr.state_outgrew_its_start_per_row(atol, rtol, states, sizes)
    alone = [
        wr.state_outgrew_its_start(atol, rtol, y, s) for y, s in zip(states, sizes, strict=True)
    ]
    np.testing.assert_array_equal(_mixed(rows), alone)
    tolerances = ar.auto_tolerance_per_row(atol, rtol, states)
    np.testing.assert_array_equal(tolerances, [ar.auto_tolerance(atol, rtol, y) for y in states])


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
    from hamrkq.solve.auto import reruns_with_witness, witness_rerun_needed
    from hamrkq.solve.growth import MIN_GROWTH_STEPS, folded_growth
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
        factor = early = 1.0
        if steps >= MIN_GROWTH_STEPS and nodes >= 3:
            y_size = batch.y_size[i]
            factor = folded_growth(task, batch.gamma_to_middle[i], batch.gamma_to_end[i], y_size)
            early = folded_growth(task, batch.gamma_to_early[i], batch.gamma_to_end[i], y_size)
        step_range = float(batch.step_range[i])
        rerun[i] = witness_rerun_needed(
            task, request.y0[i], batch.y_size[i], factor, steps, step_range, early
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


@pytest.mark.parametrize("t_eval", [None, np.linspace(0.0, 150.0, 7)])
def test_members_near_the_separatrix_run_again_as_solve_alone_decides(monkeypatch, t_eval):
    """Pendulum librations with rk67q12 at atol 1e-9 over [0, 150]: 1e-6
    below the separatrix the estimate grows 1.8e4-fold from the first
    sixteenth of the run to its end (solve runs it again with the witness:
    the orbit's amplification), farther below it does not; the batch loop
    folds the growth from the nodes, or with ``t_eval`` from the kernel's
    checkpoint at a sixteenth, as solve reads it, and every member equals
    solve alone."""
    decided = _spy_on_the_batch(monkeypatch)
    pendulum = hamrkq.load_problem("pendulum")
    q0 = np.array([[math.pi - math.sqrt(2e-6)], [math.pi - math.sqrt(3e-6)], [1.0], [2.0]])
    options = {"t_span": (0.0, 150.0), "method": "rk67q12", "atol": 1e-9, "t_eval": t_eval}
    ens = hamrkq.ensemble(pendulum, q0=q0, p0=np.zeros_like(q0), workers=1, chunk_size=4,
                          **options)  # fmt: skip
    ((again, saturated, rerun),) = decided
    np.testing.assert_array_equal(again, saturated | rerun)
    np.testing.assert_array_equal(rerun, [True, True, False, False])
    for i in range(len(q0)):
        _assert_member_equals_solve(ens, i, pendulum, **options)


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


def test_the_rules_after_a_run_per_row_give_solve_s_hand_computed_decisions():
    """hamrkq.solve.member_rules on Henon-Heiles runs at atol 1e-8 from
    q = p = (0.18, 0.18) (each half's scale 0.18, so 5.4e-11 at 3e-10 of
    it): the growth of the estimate over the second half, and whether a run
    is made again with the witness, by hand; one run alone as its row of
    many.  The shadow estimate (rk78q12): an exponential growth (over 50),
    or the length's law at the run's largest state, times the larger of the
    close approaches' factor and the orbit's amplification (the growth from
    the first sixteenth over ``REGULAR_GROWTH``); the tangent estimate
    (rk34q8): a state grown more than 10-fold, where the rule at the start
    would call for the witness and did not."""
    from hamrkq.solve import auto, member_rules, prepare

    problem = hamrkq.load_problem("henon_heiles")
    y0 = np.full(D, 0.18)
    states = np.tile(y0, (5, 1))
    to_middle = np.array([[1e-10, 2e-10, 0, 0], [0] * 4, [0] * 4, [3e-9] * 4, [1e-12, 0, 0, 0]])
    to_end = np.array([[4e-9, 1e-10, 0, 0], [0] * 4, [1e-9, 0, 0, 0], [3e-9] * 4, [6e-9, 0, 0, 0]])
    # max(to_end / 1e-8) over max(to_middle / 1e-8); none: 1; at the end only: inf
    growths = [4e-9 / 2e-10, 1.0, math.inf, 1.0, 6e-9 / 1e-12]
    shadow, tangent = (
        prepare(problem, method=method, atol=1e-8, rtol=0.0).task
        for method in ("rk78q12", "rk34q8")
    )
    for task in (shadow, tangent):
        assert auto.reruns_with_witness(task)
        growth = member_rules.folded_growth_per_row(task, to_middle, to_end, states)
        np.testing.assert_allclose(growth, growths, rtol=1e-15)
    # (factor, steps, step range, largest |q1|, early growth) -> rerun with
    # the shadow estimate
    regular = wr.REGULAR_GROWTH
    shadow_cases = [
        ((49.0, 10_000, 1.0, 0.18, 1.0), False),  # 5.4e-11 against 1e-8
        ((51.0, 10_000, 1.0, 0.18, 1.0), True),  # exponential
        ((49.0, 250_000, 1.0, 0.18, 1.0), True),  # (250 000 / 15 000)^2 = 278: 1.5e-8
        ((49.0, 100_000, 1.0, 0.18, 1.0), False),  # 44: 2.4e-9
        ((49.0, 10_000, 1000.0, 0.18, 1.0), True),  # 500 times: 2.7e-8
        ((49.0, 10_000, 1.0, 100.0, 1.0), True),  # q1 reached 100: 3e-8
        ((49.0, 10_000, 1.0, 0.18, 1000 * regular), True),  # 1000 times: 5.4e-8
        ((49.0, 10_000, 1.0, 0.18, 100 * regular), False),  # 100 times: 5.4e-9
        ((49.0, 10_000, 1.0, 0.18, math.inf), False),  # no early reading: 1
        ((49.0, 10_000, 50.0, 0.18, 10 * regular), False),  # the larger (25), not 25 x 10
    ]
    # largest |q1| -> rerun with the tangent estimate (at start 5.4e-11, unneeded)
    tangent_cases = [
        (0.18, False),  # no growth
        (3.0, False),  # 16.7-fold: 9e-10 is still below 1e-8
        (40.0, True),  # 222-fold: 1.2e-8 above 1e-8
    ]
    for task, cases in (
        (shadow, shadow_cases),
        (tangent, [((0.0, 10_000, 1.0, q1, 1e9), rerun) for q1, rerun in tangent_cases]),
    ):
        factors, steps, ranges, q1, early = (
            np.array(c) for c in zip(*(k for k, _ in cases), strict=True)
        )
        expected = [rerun for _, rerun in cases]
        rows = np.tile(y0, (len(cases), 1))
        sizes = rows.copy()
        sizes[:, 0] = q1
        decided = member_rules.witness_rerun_needed_per_row(
            task, rows, sizes, factors, steps.astype(np.int64), ranges, early
        )
        assert decided.tolist() == expected
        for k, rerun in enumerate(expected):  # one run alone (Python floats)
            one = (
                task, y0, sizes[k], float(factors[k]), int(steps[k]), float(ranges[k]),
                float(early[k]),
            )  # fmt: skip
            assert member_rules.witness_rerun_needed_per_row(*one) == rerun
            assert auto.witness_rerun_needed(*one) == rerun
