"""The user's path (issue 16): initial values by name, in the API and in files;
messages that say what to do; non-smooth H (Abs) integrates."""

import warnings

import numpy as np
import pytest
import sympy as sp

import hamrkq
from hamrkq.errors import HamiltonianError, HamrkqWarning, InputError, ProblemFileError

x, v = sp.symbols("x v", real=True)
k = sp.Symbol("k", real=True)
OSC = hamrkq.Hamiltonian(v**2 / 2 + k * x**2 / 2, q=[x], p=[v], parameters={k: 4.0})


# -- the API: q0={"x": ...} ----------------------------------------------------------
def test_named_initial_values_equal_positional_ones():
    by_name = OSC.state_values({"x": 1.0}, {v: sp.Rational(1, 2)})
    assert by_name.tolist() == [1.0, 0.5]
    a = hamrkq.solve(OSC, q0={"x": 1.0}, p0={"v": 0.5}, t_span=(0, 3), atol=1e-8)
    b = hamrkq.solve(OSC, q0=[1.0], p0=[0.5], t_span=(0, 3), atol=1e-8)
    np.testing.assert_array_equal(a.y, b.y)
    # and against the exact solution x = cos 2t + sin(2t)/4 (omega = 2)
    exact = np.cos(2 * a.t) + 0.5 / 2 * np.sin(2 * a.t)
    np.testing.assert_allclose(a.q[:, 0], exact, atol=1e-7)


def test_named_initial_values_order_follows_the_declaration():
    q1, q2, p1, p2 = sp.symbols("q1 q2 p1 p2", real=True)
    ham = hamrkq.Hamiltonian((p1**2 + p2**2) / 2 + q1 * q2, q=[q1, q2], p=[p1, p2])
    y0 = ham.state_values({"q2": 2.0, "q1": 1.0}, {p2: 4.0, "p1": 3.0})
    assert y0.tolist() == [1.0, 2.0, 3.0, 4.0]


@pytest.mark.parametrize(
    ("q0", "p0", "fragments"),
    [
        ({"x": 1.0, x: 2.0}, {"v": 0}, ["q0", "x is bound twice", "1.0", "2.0"]),
        ({"v": 1.0}, {"v": 0}, ["q0", "'v' is not a coordinate", "p0"]),
        ({"y": 1.0}, {"v": 0}, ["q0", "unknown coordinate 'y' = 1.0", "coordinates are x"]),
        ({"x": 1.0}, {}, ["p0", "no value for v"]),
        ({"x": "1"}, {"v": 0}, ["q0['x']", "string '1'"]),
    ],
)
def test_named_initial_values_errors_name_key_and_value(q0, p0, fragments):
    with pytest.raises((InputError, TypeError)) as info:
        OSC.state_values(q0, p0)
    for fragment in fragments:
        assert fragment in str(info.value), str(info.value)


# -- files: [initial] x = ..., v = ... ------------------------------------------------
NAMED = """\
name = "{name}"
coordinates = ["x", "y"]
momenta = ["u", "v"]
hamiltonian = "(u**2 + v**2)/2 + k*(x**2 + y**2)/2 + x*y/10"

[parameters]
k = 2

[initial]
{initial}

[integration]
t_span = [0, 5]
atol = 1e-9
"""
BY_NAME = 'y = 0.25\nx = "sqrt(k)/2"\nv = [0.5]\nu = 0'
BY_LIST = 'q = ["sqrt(k)/2", 0.25]\np = [0, 0.5]'


def write(tmp_path, initial, name="named"):
    path = tmp_path / f"{name}.toml"
    path.write_text(NAMED.format(name=name, initial=initial))
    return path


def test_file_binds_initial_values_by_name(tmp_path):
    named = hamrkq.load_problem(write(tmp_path, BY_NAME))
    listed = hamrkq.load_problem(write(tmp_path, BY_LIST, name="listed"))
    assert named.y0.tolist() == [np.sqrt(2) / 2, 0.25, 0.0, 0.5]
    np.testing.assert_array_equal(named.y0, listed.y0)
    # parameters still reach the initial values
    assert named.with_parameters(k=8).q0[0] == pytest.approx(np.sqrt(8) / 2)


@pytest.mark.parametrize(("coordinates", "momenta"), [("x", "p"), ("q", "v"), ("q", "p")])
def test_file_lists_bind_where_a_coordinate_is_named_q_or_a_momentum_p(
    tmp_path, coordinates, momenta
):
    """The lists q = [...] and p = [...] were refused as "mixing the lists q
    with the names p" where the momentum is named p (QA)."""
    text = f"""
name = "named_qp"
coordinates = ["{coordinates}"]
momenta = ["{momenta}"]
hamiltonian = "{momenta}**2/2 + {coordinates}**2/2"

[initial]
q = [0.5]
p = [0.25]

[integration]
t_span = [0, 1]
"""
    path = tmp_path / "named_qp.toml"
    path.write_text(text)
    assert hamrkq.load_problem(path).y0.tolist() == [0.5, 0.25]


@pytest.mark.parametrize(
    ("settings", "key", "fragment"),
    [
        ('z_method = "dop853"', "z_method", "the file's method 'auto' has no quencher"),
        ('method = "rk34"\nglobal_error_estimate = "tangent"', "global_error_estimate", "rk34"),
        ("step = 0.1", "step", "applies only to the fixed-step methods"),
        ('method = "gauss4"', "method", "its step must be set too"),
        ('method = "verlet"\nstep = 0.1\natol = 1e-8', "atol", "a fixed-step method"),
    ],
)
def test_file_settings_its_own_method_has_no_use_for_are_refused(
    tmp_path, settings, key, fragment
):
    """They were dropped without a word (the run ran auto without z_method,
    rk34 without a Gamma, auto without the step; QA); gauss4 without its
    step was refused only when run."""
    text = NAMED.format(name="named", initial=BY_NAME).replace("atol = 1e-9", settings)
    path = tmp_path / "named.toml"
    path.write_text(text)
    with pytest.raises(ProblemFileError, match=f"key 'integration.{key}': .*{fragment}"):
        hamrkq.load_problem(path)


def test_file_settings_for_its_own_method_are_kept_where_another_runs(tmp_path):
    """rk34q8's z_method in its own file: left out of a run of auto."""
    text = NAMED.format(name="named", initial=BY_NAME).replace(
        "atol = 1e-9", 'method = "rk34q8"\nz_method = "cooper_verner"\natol = 1e-9'
    )
    path = tmp_path / "named.toml"
    path.write_text(text)
    problem = hamrkq.load_problem(path)
    assert problem.integration["z_method"] == "cooper_verner"
    sol = hamrkq.solve(problem, method="auto", t_span=(0, 0.5))
    assert sol.success and sol.options["z_method"] != "cooper_verner"


@pytest.mark.parametrize(
    ("initial", "fragments"),
    [
        (BY_NAME + "\nq = [1, 2]", ["key 'initial.", "mixes the lists q with the names"]),
        (BY_NAME.replace("u = 0", "w = 0"), ["key 'initial.w'", "w = 0: unknown name"]),
        (BY_NAME.replace("u = 0", "k = 0"), ["key 'initial.k'", "a parameter"]),
        (BY_NAME.replace("\nu = 0", ""), ["key 'initial'", "no initial value for u"]),
        (BY_NAME.replace("v = [0.5]", "v = [0.5, 1]"), ["initial.v", "[0.5, 1]", "one value"]),
        (BY_NAME.replace("y = 0.25", "y = 'open(1)'"), ["initial.y", "open"]),
    ],
)
def test_file_named_initial_errors_name_file_key_value(tmp_path, initial, fragments):
    with pytest.raises(ProblemFileError) as info:
        hamrkq.load_problem(write(tmp_path, initial))
    message = str(info.value)
    assert "named.toml" in message
    for fragment in fragments:
        assert fragment in message, message


# -- messages that say what to do ------------------------------------------------------
def test_coordinate_named_t_is_not_reported_as_duplicated():
    t, p = sp.symbols("t p")
    with pytest.raises(HamiltonianError) as info:
        hamrkq.Hamiltonian(p**2 / 2 + t**2 / 2, q=[t], p=[p])
    message = str(info.value)
    assert "duplicated" not in message
    assert "called 't', the name of the time symbol" in message and "rename" in message


def test_momenta_count_mismatch_says_what_to_do():
    q1, q2, p = sp.symbols("q1 q2 p")
    with pytest.raises(HamiltonianError, match="every coordinate needs its conjugate momentum"):
        hamrkq.Hamiltonian(p**2 / 2 + q1**2 + q2**2, q=[q1, q2], p=[p])


def test_symbols_with_other_assumptions_are_explained():
    q_real, p = sp.symbols("q p", real=True)
    q_plain = sp.Symbol("q")
    with pytest.raises(HamiltonianError) as info:
        hamrkq.Hamiltonian(p**2 / 2 + q_plain**2, q=[q_real], p=[p])
    message = str(info.value)
    assert "undeclared symbols: q" in message
    assert "H uses q, a symbol with other assumptions (none) than the declared q (real=True)" in (
        message
    )


def test_eulers_number_E_is_explained():
    q, p = sp.symbols("q p")
    # `from sympy import *` then E*q**2: E is 2.718..., the parameter E does nothing
    with pytest.raises(HamiltonianError, match=r"SymPy constant E = 2\.71828"):
        hamrkq.Hamiltonian(p**2 / 2 + sp.E * q**2, q=[q], p=[p], parameters={"E": 2.0})
    with pytest.raises(HamiltonianError, match=r"or a name but the SymPy constant E"):
        hamrkq.Hamiltonian(p**2 / 2 + q**2, q=[q], p=[p], parameters={sp.E: 2.0})


# -- Abs(q): DiracDelta in the Jacobian ------------------------------------------------
@pytest.mark.parametrize("backend", ["python", "numba"])
def test_abs_potential_integrates_with_a_warning(backend):
    pytest.importorskip("numba") if backend == "numba" else None
    q, p = sp.symbols("q p", real=True)
    with pytest.warns(HamrkqWarning, match="not differentiable everywhere") as record:
        ham = hamrkq.Hamiltonian(p**2 / 2 + sp.Abs(q), q=[q], p=[p])
    assert record[0].filename == __file__  # stacklevel points at the caller
    assert not ham.jacobian.has(sp.DiracDelta)
    with warnings.catch_warnings():
        warnings.simplefilter("error", HamrkqWarning)
        sol = hamrkq.solve(ham, q0=[1.0], p0=[0.0], t_span=(0, 1.2), atol=1e-9, backend=backend)
    # away from the kink q = 0 the motion is uniformly accelerated: p = -t, q = 1 - t^2/2
    assert sol.success
    np.testing.assert_allclose(sol.p[:, 0], -sol.t, atol=1e-12)
    np.testing.assert_allclose(sol.q[:, 0], 1 - sol.t**2 / 2, atol=1e-12)


# -- reports: no meaningless numbers ---------------------------------------------------
def test_time_dependent_energy_is_reported_as_not_conserved():
    from hamrkq.analysis.diagnostics import diagnose
    from hamrkq.io.report import format_table, summary_rows

    q, p, t = sp.symbols("q p t", real=True)
    # a driven oscillator: H changes along the flow by dH/dt = -q sin t
    ham = hamrkq.Hamiltonian(p**2 / 2 + q**2 / 2 + q * sp.cos(t), q=[q], p=[p])
    sol = hamrkq.solve(ham, q0=[1.0], p0=[0.0], t_span=(0, 5), atol=1e-8)
    diag = diagnose(sol, ham, reference="rk8")
    assert abs(sol.energy[-1] - sol.energy[0]) > 0.1  # the change is physics, not error
    for text in (diag.table(), format_table(summary_rows(sol, diag))):
        assert "not conserved: H depends on t" in text
        assert "energy / bound" not in text and "energy error" not in text
        assert "max |H - H(0)|" not in text
    summary = diag.to_dict()
    assert summary["energy_conserved"] is False and summary["energy_bound_ratio"] is None


def test_true_error_needs_a_reference_more_accurate_than_the_tolerance():
    from hamrkq.analysis.diagnostics import diagnose
    from hamrkq.analysis.reference import Reference
    from hamrkq.io.report import format_table, summary_rows

    sol = hamrkq.solve(OSC, q0=[1.0], p0=[0.0], t_span=(0, 3), atol=1e-8)
    exact = np.column_stack([np.cos(2 * sol.t), -2 * np.sin(2 * sol.t)])
    good = diagnose(sol, OSC, reference=Reference(sol.t, exact, 1e-15, "exact cosine"))
    text = format_table(summary_rows(sol, good))
    assert good.error_measured
    assert "max true error (independent)" in text and "reference accurate to ~1.0e-15" in text
    true_max = np.max(np.abs(sol.y - exact))
    assert good.error.max_trajectory >= true_max > 0
    # the same reference claiming to be accurate only to 1e-6 (above atol = 1e-8)
    poor = diagnose(sol, OSC, reference=Reference(sol.t, exact, 1e-6, "a loose run"))
    assert not poor.error_measured and poor.to_dict()["true_error_measured"] is False
    for text in (poor.table(), format_table(summary_rows(sol, poor))):
        assert "not measured: the reference (a loose run) is accurate only to ~1.0e-06" in text
        assert "tolerance 1.0e-08" in text


def test_a_fixed_step_run_without_a_tolerance_reports_its_true_error():
    """Before, every fixed-step run said 'not measured ... not below the
    tolerance nan': the comparison with its nan tolerance was always false."""
    from hamrkq.analysis.diagnostics import diagnose
    from hamrkq.analysis.reference import Reference

    sol = hamrkq.solve(OSC, q0=[1.0], p0=[0.0], t_span=(0, 3), method="gauss4", step=0.1)
    assert np.all(np.isnan(sol.atol))
    exact = np.column_stack([np.cos(2 * sol.t), -2 * np.sin(2 * sol.t)])
    good = diagnose(sol, OSC, reference=Reference(sol.t, exact, 1e-15, "exact cosine"))
    error = np.abs(sol.y - exact).max()
    assert good.error_measured and max(good.error.max_abs) == error
    assert 1e-9 < error < 1e-4  # Gauss4 at h = 0.1 (h^4 ~ 1e-4 times a small constant)
    # a reference not ten times more accurate than the error it would measure
    poor = diagnose(sol, OSC, reference=Reference(sol.t, exact, error, "a loose run"))
    assert not poor.error_measured
    assert "not below a tenth of the error it measures," in poor.error_note


def test_no_true_error_figures_where_the_true_error_is_not_measured(tmp_path):
    """Before, hamrkq run pleiades drew figure2_global_error_true.png ("numerical
    minus reference") while its summary said the true error was not measured
    (the reference accurate only to 2.1e-8 against a tolerance of 1e-8)."""
    from hamrkq.analysis.diagnostics import diagnose
    from hamrkq.analysis.reference import Reference
    from hamrkq.cli.run import write_figures
    from hamrkq.io.report import OutputDir

    sol = hamrkq.solve(OSC, q0=[1.0], p0=[0.0], t_span=(0, 3), atol=1e-8)
    exact = np.column_stack([np.cos(2 * sol.t), -2 * np.sin(2 * sol.t)])
    for accuracy, drawn in ((1e-15, True), (1e-6, False)):
        diag = diagnose(sol, OSC, reference=Reference(sol.t, exact, accuracy, "a run"))
        out = OutputDir(tmp_path / f"acc{accuracy:g}")
        notes = write_figures(out, sol, diag, title="osc", dpi=40)
        true_figures = {"figure2_global_error_true.png", "figure3_trajectory_error_true.png"}
        assert true_figures <= set(out.written) if drawn else not true_figures & set(out.written)
        assert "figure2_global_error.png" in out.written  # the estimated error, always
        assert any("not drawn: the true error is not measured" in n for n in notes) != drawn
        out.close()


def test_the_summary_says_how_the_quencher_ran():
    from hamrkq.io.report import summary_rows

    sol = hamrkq.solve(
        OSC, q0=[1.0], p0=[0.0], t_span=(0, 1), method="rk78q12", z_substeps=3, atol=1e-8
    )
    assert dict(summary_rows(sol, None))["method"] == "rk78q12 (3 quencher steps a step)"
    extended = sol.replace(options={**sol.options, "quencher_precision": "double-double"})
    assert dict(summary_rows(extended, None))["method"] == (
        "rk78q12 (3 quencher steps a step, the quencher in double-double)"
    )


def test_named_initial_value_not_finite_names_its_own_key(tmp_path):
    path = write(tmp_path, BY_NAME.replace('x = "sqrt(k)/2"', 'x = "1/(k - 2)"'))
    with pytest.raises(ProblemFileError) as info:
        hamrkq.load_problem(path)
    assert "key 'initial.x'" in str(info.value) and "k = 2" in str(info.value)


def test_abs_of_a_symbol_not_declared_real_says_to_declare_it():
    q, p = sp.symbols("q p")  # no real=True: d|q|/dq is (re(q) re'(q) + ...)/|q|
    with pytest.raises(HamiltonianError, match=r"Abs or sign of q, not declared real.*real=True"):
        hamrkq.Hamiltonian(p**2 / 2 + sp.Abs(q), q=[q], p=[p])


def test_a_file_may_ask_for_method_auto(tmp_path):
    from hamrkq.options import METHOD_NAMES

    if "auto" not in METHOD_NAMES:
        pytest.skip("solve has no method 'auto' yet")
    path = write(tmp_path, BY_NAME)
    path.write_text(path.read_text().replace("atol = 1e-9", 'atol = 1e-9\nmethod = "auto"'))
    problem = hamrkq.load_problem(path)
    assert problem.integration["method"] == "auto"


def test_a_relative_tolerance_run_has_its_true_error_measured():
    """Before, the reports compared the reference's accuracy with the
    smallest tolerance of any component at any node, which with rtol and a
    tiny atol is atol where a component crosses zero: ``hamrkq run harmonic
    --rtol 1e-8 --atol 1e-20`` said "not measured: ... not below the
    tolerance 1.0e-20" against its exact solution (accurate to 1e-15)."""
    from hamrkq.analysis.adequacy import tolerance_scale
    from hamrkq.analysis.diagnostics import diagnose

    sol = hamrkq.solve(OSC, q0=[1.0], p0=[0.0], t_span=(0, 10), rtol=1e-8, atol=1e-20)
    exact = np.column_stack([np.cos(2 * sol.t), -2 * np.sin(2 * sol.t)])
    diag = diagnose(sol, OSC, reference=hamrkq.analysis.reference.Reference(
        sol.t, exact, 1e-15, "exact cosine"))  # fmt: skip
    assert diag.error_measured and diag.error_note is None
    assert max(diag.error.max_abs) == np.abs(sol.y - exact).max() > 0
    # each component's largest tolerance along the run, the smallest of those
    delta = np.maximum(1e-20, 1e-8 * np.abs(sol.y))
    assert tolerance_scale(delta) == min(delta[:, 0].max(), delta[:, 1].max())
    assert delta.min() < 1e-12 < tolerance_scale(delta)  # q crosses zero
    # absolute tolerances, one per component: the smallest, as before
    assert tolerance_scale(np.tile([1e-6, 1e-9], (5, 1))) == 1e-9
