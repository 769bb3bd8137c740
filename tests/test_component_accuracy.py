"""A reference's accuracy is judged per component against that component's
tolerance (hamrkq.analysis.summaries, hamrkq.analysis.reference).

Found by QA: the outer solar system's true error was never measured, because
the independent reference's max-norm accuracy (2.4e-10, in the positions of
30 AU) was compared with the smallest component tolerance (1.1e-19, Pluto's
momentum), though each component's reference error is below 5e-4 of its own
tolerance.
"""

import numpy as np
import pytest
import sympy as sp

import hamrkq
from hamrkq.analysis.adequacy import accuracy_ratios, reference_is_close
from hamrkq.analysis.diagnostics import diagnose
from hamrkq.analysis.reference import Accuracy, Reference, hamiltonian_reference
from hamrkq.result import Solution, Status

#: Two uncoupled oscillators of amplitude 30 and 1e-9, each with an absolute
#: tolerance on its own scale: a cheap stand-in for the outer solar system's
#: positions and Pluto's momentum.
Y0 = (30.0, 1e-9, 0.0, 0.0)
ATOL = (1e-8, 1e-17, 1e-8, 1e-17)


def _two_scales() -> hamrkq.Hamiltonian:
    q1, q2, p1, p2 = sp.symbols("q1 q2 p1 p2")
    return hamrkq.Hamiltonian((p1**2 + q1**2 + p2**2 + q2**2) / 2, q=[q1, q2], p=[p1, p2])


def _exact(t: np.ndarray) -> np.ndarray:
    c, s = np.cos(t), np.sin(t)
    return np.column_stack([Y0[0] * c, Y0[1] * c, -Y0[0] * s, -Y0[1] * s])


def test_two_scale_run_has_its_true_error_measured_per_component():
    ham = _two_scales()
    sol = hamrkq.solve(ham, q0=Y0[:2], p0=Y0[2:], t_span=(0, 20), atol=np.array(ATOL), rtol=0.0)
    ref = hamiltonian_reference(ham, sol.y[0], sol.t, cache=False)
    exact = _exact(sol.t)
    # the per-component estimate bounds each component's actual error
    actual = np.max(np.abs(ref.y - exact), axis=0)
    assert np.all(actual <= np.array(ref.component_error))
    # on the small oscillator the reference is far better than the max-norm
    assert ref.component_error[1] < 1e-6 * ref.estimated_error
    assert ref.estimated_error.components == ref.component_error
    diag = diagnose(sol, ham, reference="independent")
    # max-norm accuracy over the smallest tolerance is far above 1 ...
    assert diag.error.reference_accuracy > 1e-17
    # ... yet each component's is below its own tolerance: measured
    assert diag.error_measured and diag.error_note is None
    assert diag.error.component_accuracy == pytest.approx(ref.component_error)
    true = np.max(np.abs(sol.y - exact), axis=0)
    assert diag.error.max_abs == pytest.approx(true, rel=0.01, abs=1e-25)
    assert diag.to_dict()["global_error"]["component_accuracy"]["q2"] == ref.component_error[1]


def _solution(y, atol):
    t = np.linspace(0.0, 1.0, y.shape[0])
    return Solution(
        t=t, y=y, energy=np.zeros(t.size), z=None, gamma=None, global_error=None,
        status=Status.SUCCESS, message="ok", method="rk34q8", n=2,
        names=("q1", "q2", "p1", "p2"), atol=np.array(atol), rtol=0.0,
        stats={"steps": t.size - 1, "rejected": 0, "quenches": 0, "nfev": 1},
    )  # fmt: skip


def test_short_component_is_named_and_advice_is_true():
    y = np.tile(np.array(Y0), (5, 1))
    sol = _solution(y, ATOL)
    # q2 is known to 2e-17, above its tolerance 1e-17: not measured, and the
    # note names q2 and its tolerance, not the max-norm against the smallest
    ref = Reference(
        t=sol.t, y=y, estimated_error=1e-12, method="test",
        component_error=(1e-12, 2e-17, 1e-12, 1e-27),
    )  # fmt: skip
    diag = diagnose(sol, reference=ref)
    assert not diag.error_measured
    assert "~2.0e-17 in q2, not below q2's tolerance 1.0e-17" in diag.error_note
    assert "reference='extended'" in diag.error_note
    # a tolerance below half an ulp of the values: no reference in double
    # measures it, and the extended one is not suggested
    tight = _solution(y, (1e-8, 1e-26, 1e-8, 1e-17))
    ref = Reference(
        t=tight.t, y=y, estimated_error=1e-12, method="test",
        component_error=(1e-12, 1e-25, 1e-12, 1e-27),
    )  # fmt: skip
    note = diagnose(tight, reference=ref).error_note
    assert "no reference rounded to double reaches it" in note
    assert "extended" not in note


def test_accuracy_without_components_is_the_max_norm_for_each():
    delta = np.array([[1e-8, 1e-17]])
    assert list(accuracy_ratios(1e-12, delta)) == pytest.approx([1e-4, 1e5])
    assert list(accuracy_ratios(Accuracy(1e-12, (1e-12, 1e-21)), delta)) == pytest.approx(
        [1e-4, 1e-4]
    )
    # close: some component's accuracy above a hundredth of its tolerance
    assert reference_is_close(Accuracy(1e-12, (1e-12, 2e-19)), delta)
    assert not reference_is_close(Accuracy(1e-12, (1e-12, 1e-21)), delta)


def test_accuracy_survives_pickling_and_the_cache(tmp_path, monkeypatch):
    import pickle

    value = Accuracy(2e-10, (2e-10, 3e-20))
    again = pickle.loads(pickle.dumps(value))
    assert again == value and again.components == value.components
    monkeypatch.setenv("HAMRKQ_CACHE_DIR", str(tmp_path))
    ham = _two_scales()
    t = np.linspace(0.0, 5.0, 11)
    first = hamiltonian_reference(ham, Y0, t)
    kept = hamiltonian_reference(ham, Y0, t)
    assert kept.component_error == first.component_error is not None


@pytest.mark.slow
def test_outer_solar_system_true_error_is_measured():
    """QA's case: over [0, 20000] the reference's max-norm accuracy (2.4e-10)
    is far above the smallest tolerance (1.1e-19, Pluto's momentum), but in
    each component it is below a hundredth of that component's tolerance."""
    from hamrkq.analysis.adequacy import tolerance_scale

    problem = hamrkq.load_problem("outer_solar_system")
    sol = hamrkq.solve(problem, t_span=(0, 20000))
    diag = diagnose(sol, problem, reference="independent")
    assert tolerance_scale(diag.series["delta"]) == pytest.approx(1.1e-19, rel=0.05)
    assert diag.error.reference_accuracy > 1e-10
    ratios = accuracy_ratios(
        diag.error.reference_accuracy, diag.series["delta"], diag.error.component_accuracy
    )
    assert np.max(ratios) < 0.01
    assert diag.error_measured and not diag.reference_close
    # QA measured 1.088e-8 against heyoka in quad precision
    assert max(diag.error.max_abs) == pytest.approx(1.088e-8, rel=0.01)
