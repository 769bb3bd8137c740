"""Bad input to hamrkq.solve raises at once, with the parameter and the value
named in the message; nothing from the input is ever evaluated as code."""

import numpy as np
import pytest
import sympy as sp

from hamrkq.catalogue.problems import load_problem
from hamrkq.errors import InputError, InputTypeError, OptionError
from hamrkq.solve import solve
from hamrkq.symbolic.hamiltonian import Hamiltonian

q, p, a = sp.symbols("q p a")
HAM = Hamiltonian((p**2 + q**2) / 2, q=[q], p=[p])


def call(**changes):
    args = {"q0": [0.0], "p0": [1.0], "t_span": (0, 1)}
    args.update(changes)
    return solve(HAM, args.pop("q0"), args.pop("p0"), args.pop("t_span"), **args)


@pytest.mark.parametrize(
    ("changes", "error", "pattern"),
    [
        ({"q0": [0.0, 1.0]}, InputError, "q0 has 2 values"),
        ({"p0": [np.nan]}, InputError, "p0.*finite"),
        ({"q0": "0.5"}, InputTypeError, "q0"),
        ({"q0": [a]}, InputError, "free symbols"),
        ({"t_span": (0, 1, 2)}, InputError, "t_span must be two numbers"),
        ({"t_span": (0, np.inf)}, InputError, "t_span must be finite"),
        ({"t_span": ("0", 1)}, InputTypeError, "t_span\\[0\\].*string"),
        ({"atol": 0.0}, InputError, "atol must be finite and positive, got 0.0"),
        ({"atol": 0.0, "rtol": 1e-8}, InputError, "give rtol with a tiny atol, 1e-20 say"),
        ({"atol": -1e-6}, InputError, "atol.*-1e-06"),
        ({"atol": [1e-6, 1e-6, 1e-6]}, InputError, "atol must be a scalar or have 2 entries"),
        ({"atol": np.nan}, InputError, "atol must be finite"),
        ({"atol": "1e-6"}, InputTypeError, "atol.*'1e-6'"),
        ({"rtol": -1.0}, InputError, "rtol must be finite and zero or positive"),
        ({"method": "rk45"}, OptionError, "method='rk45'.*'auto', 'rk34q8', 'rk34'"),
        ({"quench": "always"}, OptionError, "quench='always'.*'node', 'redo'"),
        ({"tolerance_rule": "mixed"}, OptionError, "'componentwise', 'prentice'"),
        ({"global_error_estimate": "exact"}, OptionError, "'tangent', 'paper', 'shadow', 'off'"),
        ({"z_method": "rk4"}, OptionError, "z_method='rk4'.*'dop853', 'cooper_verner'"),
        # z_method replaces an 8th-order quencher; elsewhere it is refused, not ignored
        (
            {"method": "rk78q12", "z_method": "cooper_verner"},
            OptionError,
            "quencher of 'rk34q8', 'rk45q8', 'rk56q8'; 'rk78q12' has the order-12 quencher "
            "'feagin12'",
        ),
        ({"method": "auto", "z_method": "dop853"}, OptionError, "quenchers of order 9 to 12"),
        ({"method": "rk34", "z_method": "dop853"}, OptionError, "'rk34' has no quencher"),
        ({"method": "verlet", "step": 0.1, "z_method": "dop853"}, OptionError, "needs an RKQ"),
        ({"backend": "cuda"}, OptionError, "backend='cuda'.*'auto', 'numba', 'python'"),
        # an option the method has no use for is refused, not ignored: gauss4
        # with max_step=1e-3 ran steps of 0.1 without a word
        (
            {"method": "gauss4", "step": 0.1, "max_step": 1e-3},
            OptionError,
            "max_step=0.001 does not apply to method='gauss4'",
        ),
        ({"method": "verlet", "step": 0.1, "gamma_limit": 0.01}, OptionError, "fixed-step"),
        ({"method": "verlet", "step": 0.1, "safety": 0.8}, OptionError, "safety=0.8"),
        ({"method": "scipy:DOP853", "quench": "redo"}, OptionError, "SciPy's solver"),
        ({"method": "scipy:DOP853", "tolerance_rule": "prentice"}, OptionError, "SciPy"),
        ({"method": "rk34", "z_substeps": 3}, OptionError, "the pair alone"),
        ({"method": "scipy:RK34Q8", "z_substeps": 3}, OptionError, "SciPy's OdeSolver"),
        ({"method": "rk34", "global_error_estimate": "off"}, OptionError, "without a quencher"),
        # y0 as SciPy takes it: 1-D (a transposed or nested array is a slip)
        ({"q0": [[0.0]]}, InputError, r"q0 must be 1-dimensional .*shape \(1, 1\)"),
        ({"p0": np.ones((1, 1))}, InputError, "p0 must be 1-dimensional"),
        # a SymPy matrix is a vector only as a row or a column (a 2 x 3 one was
        # flattened row by row)
        ({"q0": sp.zeros(2, 2)}, InputError, r"q0 must be 1-dimensional .*\(2, 2\)"),
        ({"safety": 0.0}, InputError, "safety must be a positive number, got 0.0"),
        ({"safety": 1.5}, InputError, "safety must be at most 1.0, got 1.5"),
        ({"quench_threshold": -1}, InputError, "quench_threshold.*-1"),
        ({"max_step": 0}, InputError, "max_step must be a positive number, got 0"),
        ({"max_steps": 0}, InputError, "max_steps must be a positive integer, got 0"),
        ({"max_steps": 10.5}, InputError, "max_steps.*10.5"),
        ({"keep_every": 0}, InputError, "keep_every must be a positive integer"),
        # QA: 10**12 quencher steps a step was accepted and never ended a step
        ({"method": "rk67q9", "z_substeps": 10**12}, InputError, "z_substeps must be at most"),
        ({"first_step": -0.1}, InputError, "first_step must be a positive number"),
        ({"first_step": 2.0}, InputError, "first_step=2.0 exceeds the length of t_span"),
        # below the loop's roundoff floor (10 eps |t|): the run ended on its
        # first step with "The step size 0 fell below ...", naming neither
        (
            {"t_span": (1e8, 1e8 + 1), "first_step": 1e-9},
            InputError,
            "first_step=1e-09 is below the shortest step the time's rounding allows",
        ),
        ({"t_span": (-50, -40), "max_step": 1e-14}, InputError, "max_step=1e-14 is below"),
        ({"gamma_limit": 0}, InputError, "gamma_limit must be a positive number"),
        (
            {"t_eval": [0.5, 2.0]},
            InputError,
            r"t_eval must lie within t_span .*: t_eval\[1\] = 2.0$",
        ),
        # np.arange's rounding past t_end is named as such, with the remedy (QA)
        (
            {"t_span": (0, 0.3), "t_eval": np.arange(4) * 0.1},
            InputError,
            r"t_eval\[3\] = 0.30000000000000004 is 1 ulp past 0.3, a rounding .*np.linspace",
        ),
        ({"t_eval": [0.5, 0.2]}, InputError, "strictly monotonic"),
        ({"t_eval": [0.2, 0.5], "keep_every": 2}, InputError, "keep_every=2 and t_eval"),
        ({"parameters": {"b": 1.0}}, InputError, "unknown parameter b"),
        ({"parameters": [1.0]}, InputTypeError, "parameters must be a mapping"),
        ({"progress": "yes"}, InputTypeError, "progress must be a bool or a callable"),
    ],
)
def test_bad_input_is_named(changes, error, pattern):
    with pytest.raises(error, match=pattern):
        call(**changes)


def test_backward_t_eval_must_run_backward():
    with pytest.raises(InputError, match="strictly monotonic"):
        call(t_span=(1, 0), t_eval=[0.2, 0.5])
    sol = call(t_span=(1, 0), t_eval=[0.5, 0.2])
    assert sol.t.tolist() == [0.5, 0.2]


def test_hamiltonian_needs_initial_values_and_span():
    with pytest.raises(InputError, match="q0, t_span must be given"):
        solve(HAM, p0=[1.0])


def test_system_must_be_a_hamiltonian_or_problem():
    with pytest.raises(InputTypeError, match=r"Hamiltonian or a hamrkq\.Problem, got str"):
        solve("prentice2011")


def test_problem_file_settings_are_validated_like_keywords():
    pr = load_problem("harmonic")
    bad = type(pr)(**{**pr.__dict__, "integration": {"method": "euler"}})
    with pytest.raises(OptionError, match="method='euler'"):
        solve(bad)


def test_strings_are_never_evaluated(monkeypatch):
    import builtins

    def forbidden(*args, **kwargs):
        raise AssertionError("eval/exec called")

    monkeypatch.setattr(builtins, "eval", forbidden)
    monkeypatch.setattr(builtins, "exec", forbidden)
    monkeypatch.setattr(sp, "sympify", forbidden)
    for changes in ({"atol": "__import__('os')"}, {"q0": ["1+1"]}, {"t_span": ("0", "1")}):
        with pytest.raises((InputError, InputTypeError)):
            call(**changes)


def test_options_a_method_can_use_are_accepted():
    """The other side of the refusals above: what each kind of method uses."""
    assert call(method="verlet", step=0.1, keep_every=2, max_steps=100).success
    assert call(method="scipy:DOP853", max_step=0.1, first_step=0.01).success
    assert call(method="rk34", safety=0.8, tolerance_rule="prentice", max_step=0.5).success
    assert call(method="rk67q9", gamma_limit=0.01, z_substeps=3, quench="redo").success
    assert call(method="scipy:RK34Q8", gamma_limit=0.01).success
    assert call(q0=sp.Matrix([0.0])).success  # a SymPy column vector is 1-D enough
    # a problem file's settings are defaults: they apply where they can
    pend = load_problem("pendulum")
    assert "atol" in pend.integration
    assert solve(pend, method="verlet", step=0.1, t_span=(0, 1)).success
