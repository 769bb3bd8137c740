"""Bad input everywhere, in one table per entry point: the library, problem
files and the command line.

Each row gets the documented exception (a ``ValueError``/``TypeError``
subclass from :mod:`hamrkq.errors`) with a message naming the parameter, or
the file, line and key, and the offending value; on the command line, exit
status 2 for bad input and 1 for a failed run, a one-line message and no
traceback.  ``docs/errors.md`` documents all of it.
"""

import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

import hamrkq
from hamrkq.cli import main
from hamrkq.errors import (
    ExpressionError,
    HamiltonianError,
    HamrkqError,
    HamrkqWarning,
    InputError,
    InputTypeError,
    OptionError,
    ProblemFileError,
    ProblemNotFoundError,
    UndeclaredSymbolError,
)
from hamrkq.result import Solution, Status
from hamrkq.symbolic.expressions import MAX_DEPTH, MAX_LENGTH, parse_expression

ROOT = Path(__file__).resolve().parent.parent
q, p, x, y, px, py, a, b = sp.symbols("q p x y px py a b", real=True)
HAM = hamrkq.Hamiltonian(p**2 / 2 + a * q**2 / 2, q=[q], p=[p], parameters={a: 1.0})
NO_DEFAULT = hamrkq.Hamiltonian(p**2 / 2 + a * q**2 / 2, q=[q], p=[p], parameters=[a])
HAM2 = hamrkq.Hamiltonian((px**2 + py**2 + x**2 + y**2) / 2, q=[x, y], p=[px, py])


def solve1(**changes):
    """solve HAM with one argument changed."""
    args = {"q0": [0.0], "p0": [1.0], "t_span": (0, 1), **changes}
    return hamrkq.solve(HAM, args.pop("q0"), args.pop("p0"), args.pop("t_span"), **args)


# -- the library -------------------------------------------------------------------
# (call, exception class, regular expression the message must match)
LIBRARY = [
    # initial values
    pytest.param(lambda: solve1(q0=[0.0, 1.0]), InputError,
                 r"q0 has 2 values but the system has 1 degree of freedom", id="q0-length"),
    pytest.param(lambda: hamrkq.solve(HAM2, [0, 0], [1], (0, 1)), InputError,
                 r"p0 has 1 value but the system has 2 degrees", id="p0-length"),
    pytest.param(lambda: solve1(q0=[np.nan]), InputError, r"q0\[0\].*finite.*nan", id="q0-nan"),
    pytest.param(lambda: solve1(p0=[-np.inf]), InputError, r"p0\[0\].*finite.*inf", id="p0-inf"),
    pytest.param(lambda: solve1(q0="0.5"), InputTypeError, r"q0 must be a sequence of numbers",
                 id="q0-string"),
    pytest.param(lambda: solve1(q0=[None]), InputTypeError, r"q0\[0\] must be a real number",
                 id="q0-none"),
    pytest.param(lambda: solve1(p0=[1 + 2j]), InputTypeError, r"p0\[0\] must be a real number",
                 id="p0-complex"),
    pytest.param(lambda: solve1(q0=[a + 1]), InputError, r"q0\[0\].*free symbols", id="q0-free"),
    pytest.param(lambda: solve1(q0=[sp.acos(2)]), InputError, r"q0\[0\] = acos\(2\) is not real",
                 id="q0-not-real"),
    # the time span
    pytest.param(lambda: solve1(t_span=(0, 1, 2)), InputError,
                 r"t_span must be two numbers \(t0, t_end\), got \(0, 1, 2\)", id="span-three"),
    pytest.param(lambda: solve1(t_span=5), InputError, r"t_span must be two numbers.*got 5",
                 id="span-scalar"),
    pytest.param(lambda: solve1(t_span=(0, np.inf)), InputError, r"t_span must be finite",
                 id="span-inf"),
    pytest.param(lambda: solve1(t_span=(0, "1")), InputTypeError,
                 r"t_span\[1\] must be a number, not the string '1'", id="span-string"),
    # tolerances
    pytest.param(lambda: solve1(atol=0.0), InputError,
                 r"atol must be finite and positive, got 0.0", id="atol-zero"),
    pytest.param(lambda: solve1(atol=[1e-6, -1e-6]), InputError,
                 r"atol must be finite and positive, got \[1e-06, -1e-06\]", id="atol-negative"),
    pytest.param(lambda: solve1(atol=[1e-6] * 3), InputError,
                 r"atol must be a scalar or have 2 entries", id="atol-shape"),
    pytest.param(lambda: solve1(atol=[[1e-6, 1e-6]]), InputError,
                 r"atol must be a scalar or have 2 entries", id="atol-2d"),
    pytest.param(lambda: solve1(rtol=np.nan), InputError,
                 r"rtol must be finite and zero or positive, got nan", id="rtol-nan"),
    pytest.param(lambda: solve1(rtol="1e-6"), InputTypeError, r"rtol.*'1e-6'", id="rtol-string"),
    # methods, options and keywords
    pytest.param(lambda: solve1(method="rk45"), OptionError,
                 r"method='rk45' is not valid; valid values: 'auto', 'rk34q8', 'rk34'",
                 id="method"),
    pytest.param(lambda: solve1(method="RK34Q8"), OptionError, r"method='RK34Q8'",
                 id="method-case"),
    pytest.param(lambda: solve1(quench="always"), OptionError, r"quench='always'.*'node', 'redo'",
                 id="quench"),
    pytest.param(lambda: solve1(global_error_estimate="exact"), OptionError,
                 r"'tangent', 'paper', 'shadow', 'off'", id="gamma-mode"),
    pytest.param(lambda: solve1(backend="gpu"), OptionError, r"backend='gpu'", id="backend"),
    pytest.param(lambda: solve1(max_steps=0), InputError,
                 r"max_steps must be a positive integer, got 0", id="max-steps"),
    pytest.param(lambda: solve1(first_step=-0.1), InputError,
                 r"first_step must be a positive number, got -0.1", id="first-step"),
    # Python's own TypeError names an unknown keyword: never a silent sink.
    pytest.param(lambda: solve1(atoll=1e-6), TypeError,
                 r"unexpected keyword argument 'atoll'", id="unknown-keyword"),
    # parameters
    pytest.param(lambda: hamrkq.solve(NO_DEFAULT, [0.0], [1.0], (0, 1)), InputError,
                 r"no value for parameter\(s\): a", id="param-missing"),
    pytest.param(lambda: solve1(parameters={"a": "2"}), InputTypeError,
                 r"parameter a must be a number, not the string '2'", id="param-string"),
    pytest.param(lambda: solve1(parameters={"a": b}), InputError,
                 r"parameter a = b has free symbols", id="param-symbol"),
    pytest.param(lambda: solve1(parameters={"b": 1.0}), InputError,
                 r"unknown parameter b \(parameters: a\)", id="param-unknown"),
    pytest.param(lambda: solve1(parameters=[1.0]), InputTypeError,
                 r"parameters must be a mapping", id="param-not-mapping"),
    pytest.param(lambda: hamrkq.solve("prentice2011"), InputTypeError,
                 r"Hamiltonian or a hamrkq\.Problem, got str", id="system-string"),
    # Hamiltonians
    pytest.param(lambda: hamrkq.Hamiltonian(p**2 + b * q, q=[q], p=[p]), UndeclaredSymbolError,
                 r"undeclared symbols: b", id="ham-undeclared"),
    pytest.param(lambda: hamrkq.Hamiltonian("p**2/2", q=[q], p=[p]), HamiltonianError,
                 r"H is a string.*never evaluates text", id="ham-string"),
    pytest.param(lambda: hamrkq.Hamiltonian(p**2 + q, q=[q, a], p=[p]), HamiltonianError,
                 r"q has 2 symbols but p has 1: every coordinate needs its", id="ham-lengths"),
    # strings for symbols: "which is not a SymPy Symbol" without "q and p are
    # empty" beside it, which the strings' being left out had made up (QA)
    pytest.param(lambda: hamrkq.Hamiltonian(p**2 + q**2, q=["q"], p=["p"]), HamiltonianError,
                 r"q contains 'q', which is not a SymPy Symbol but a string: give the symbol "
                 r"itself \(sympy\.Symbol\('q'\)\)\n.*p contains 'p'[^\n]*$", id="ham-strings"),
    pytest.param(lambda: hamrkq.Hamiltonian(p**2 + a * q, q=[q], p=[p], parameters={a: np.nan}),
                 HamiltonianError, r"parameter a must be finite, got nan", id="ham-param-nan"),
    # catalogue and expressions
    pytest.param(lambda: hamrkq.load_problem("no_such_problem"), ProblemNotFoundError,
                 r"no problem named 'no_such_problem' in the catalogue \(known: .*kepler",
                 id="load-unknown"),
    pytest.param(lambda: hamrkq.load_problem(5), InputTypeError,
                 r"name_or_path must be a catalogue name or a path, got 5", id="load-int"),
    pytest.param(lambda: hamrkq.load_problem(ROOT / "problems"), ProblemNotFoundError,
                 r"is not a file", id="load-directory"),
    pytest.param(lambda: hamrkq.load_problem("kepler", e=1.0), ProblemFileError,
                 r"kepler\.toml, key 'initial\.p\[1\]': .* is not a finite real number for the "
                 r"parameters e = 1", id="kepler-e=1"),
    pytest.param(lambda: hamrkq.load_problem("kepler", e="x"), InputTypeError,
                 r"parameter e must be a number, not the string 'x'", id="load-param-string"),
    pytest.param(lambda: hamrkq.load_problem("kepler", zz=1.0), InputError,
                 r"problem 'kepler' has no parameter\(s\) zz", id="load-param-unknown"),
    pytest.param(lambda: parse_expression("__import__('os').system('true')", {}), ExpressionError,
                 r"__import__", id="expr-hostile"),
    pytest.param(lambda: parse_expression("((2**64)**64)**64", {}), ExpressionError,
                 r"numeric power too large", id="expr-power"),
    pytest.param(lambda: parse_expression("x/0", {"x": x}), ExpressionError,
                 r"undefined, infinite or not real .*zoo", id="expr-undefined"),
]  # fmt: skip


@pytest.mark.parametrize(("call", "error", "pattern"), LIBRARY)
def test_library_refuses_bad_input(call, error, pattern):
    with pytest.raises(error, match=pattern) as info:
        call()
    # Every refusal but Python's own keyword check is a hamrkq error that is
    # also a ValueError or a TypeError.
    if error is not TypeError:
        assert isinstance(info.value, HamrkqError)
        assert isinstance(info.value, ValueError | TypeError)


# Gaps found while writing this table, reported to the owner of
# hamrkq/hamiltonian.py.  strict: the day they are fixed these rows fail, and
# the marker must go.
GAPS = [
    pytest.param(lambda: hamrkq.Hamiltonian(p**2 + sp.Function("f")(q), q=[q], p=[p]),
                 id="ham-undefined-function"),
    pytest.param(lambda: hamrkq.Hamiltonian(p**2 + sp.I * q, q=[q], p=[p]), id="ham-complex"),
    pytest.param(lambda: solve1(q0=[10**400]), id="q0-overflow"),
]  # fmt: skip


@pytest.mark.parametrize("call", GAPS)
def test_unsupported_hamiltonians_and_huge_values_are_refused(call):
    with pytest.raises(InputError):
        call()


def test_rtol_below_100_eps_is_clamped_with_a_warning():
    message = r"rtol=1e-20 is below 100 eps and is raised to 2.22e-14"
    with pytest.warns(HamrkqWarning, match=message):
        sol = solve1(atol=1e-8, rtol=1e-20)
    assert sol.success and sol.rtol.tolist() == [100 * np.finfo(float).eps] * 2


# -- problem files -------------------------------------------------------------------
GOOD = """\
name = "osc"
title = "bad-input test oscillator"
coordinates = ["x"]
momenta = ["px"]
hamiltonian = "px**2/(2*m) + k*x**2/2"

[parameters]
m = 2
k = 8

[initial]
q = [1]
p = [0]

[integration]
t_span = [0, 10]
atol = 1e-8
method = "rk34q8"
"""


def edit(old, new):
    def change(text):
        assert old in text
        return text.replace(old, new, 1)

    return change


# (change of the good text, exception class, fragments; "osc.toml:N" is file and line)
FILES = [
    pytest.param(edit('title = "bad', 'title = "bad\n'), ProblemFileError,
                 ["osc.toml:2", "TOML syntax error"], id="toml-syntax"),
    pytest.param(edit("atol = 1e-8", "atol = 1e-8\natol = 1e-9"), ProblemFileError,
                 ["osc.toml:18", "TOML syntax error"], id="toml-duplicate-key"),
    pytest.param(lambda s: s + "deep = " + "[" * 3000 + "]" * 3000 + "\n", ProblemFileError,
                 ["TOML nested too deeply"], id="toml-too-deep"),
    pytest.param(lambda s: s + "# " + "x" * 1_000_000 + "\n", ProblemFileError,
                 ["the limit is 1000000"], id="file-too-large"),
    pytest.param(edit("bad-input", "bad-input \udcff"), ProblemFileError, ["not UTF-8"],
                 id="not-utf8"),
    pytest.param(edit('name = "osc"', 'name = "other"'), ProblemFileError,
                 ["osc.toml:1", "key 'name'", "name 'other' must equal the file stem 'osc'"],
                 id="name-not-stem"),
    pytest.param(lambda s: "colour = 3\n" + s, ProblemFileError,
                 ["osc.toml:1", "key 'colour'", "unknown key(s): colour"], id="unknown-key"),
    pytest.param(edit("atol = 1e-8", "atol = 1e-8\ntolerance = 1"), ProblemFileError,
                 ["osc.toml:18", "key 'integration.tolerance'", "unknown key(s)"],
                 id="unknown-integration-key"),
    pytest.param(edit('hamiltonian = "px', 'momentum = ["px"]\nhamiltonian_ = "px'),
                 ProblemFileError, ["unknown key(s): hamiltonian_, momentum"], id="missing-key"),
    pytest.param(edit("k*x**2/2", "k*x**2/2 + zeta"), ProblemFileError,
                 ["osc.toml:5", "unknown name", "zeta"], id="undeclared-name"),
    pytest.param(edit("k*x**2/2", "x.__class__"), ExpressionError,
                 ["osc.toml:5", "key 'hamiltonian'", "attribute access", "x.__class__"],
                 id="expr-attribute"),
    pytest.param(edit("k*x**2/2", "__import__('os').system('touch pwned')"), ExpressionError,
                 ["osc.toml:5", "__import__"], id="expr-import"),
    pytest.param(edit("k*x**2/2", "+".join(["x"] * (MAX_LENGTH // 2 + 1))), ExpressionError,
                 ["osc.toml:5", f"the limit is {MAX_LENGTH}"], id="expr-too-long"),
    pytest.param(edit("k*x**2/2", "sin(" * (MAX_DEPTH + 1) + "x" + ")" * (MAX_DEPTH + 1)),
                 ExpressionError, ["osc.toml:5", f"nested deeper than {MAX_DEPTH} levels"],
                 id="expr-too-deep"),
    # the expression is named, not its innermost piece (QA: a tower of powers
    # read "nested deeper than 60 levels: '2'")
    pytest.param(edit("k*x**2/2", "x" + "**2" * (MAX_DEPTH + 1)), ExpressionError,
                 ["osc.toml:5", f"nested deeper than {MAX_DEPTH} levels",
                  "signs inside one another", ": 'x**2**2**2**2"],
                 id="expr-power-tower-too-deep"),
    pytest.param(edit("k*x**2/2", "x**(10**10)"), ExpressionError,
                 ["exponent larger than 1000"], id="expr-exponent"),
    pytest.param(edit("q = [1]", 'q = ["1/0"]'), ExpressionError,
                 ["osc.toml:12", "key 'initial.q[0]'", "undefined, infinite or not real"],
                 id="initial-undefined"),
    pytest.param(edit("p = [0]", "p = [0, 1]"), ProblemFileError,
                 ["osc.toml:13", "key 'initial.p'", "must be a list of 1 values"],
                 id="initial-length"),
    pytest.param(edit("m = 2", 'm = "sqrt(-2)"'), ExpressionError,
                 ["osc.toml:8", "key 'parameters.m'", "not real"], id="parameter-complex"),
    pytest.param(edit("m = 2", "m = true"), ExpressionError,
                 ["osc.toml:8", "a boolean is not an expression"], id="parameter-bool"),
    pytest.param(edit("t_span = [0, 10]", "t_span = [10]"), ProblemFileError,
                 ["osc.toml:16", "t_span must be a list of two values"], id="t-span-length"),
    pytest.param(edit("atol = 1e-8", 'atol = "tiny"'), ProblemFileError,
                 ["osc.toml:17", "key 'integration.atol'", "positive finite number", "'tiny'"],
                 id="atol-string"),
    pytest.param(edit("atol = 1e-8", "atol = [1e-8, -1]"), ProblemFileError,
                 ["osc.toml:17", "got [1e-08, -1]"], id="atol-negative"),
    pytest.param(edit('method = "rk34q8"', 'method = "euler"'), ProblemFileError,
                 ["osc.toml:18", "key 'integration.method'", "'euler' is not valid", "'rk34q8'"],
                 id="method-unknown"),
    pytest.param(edit('method = "rk34q8"', "max_steps = 1.5"), ProblemFileError,
                 ["osc.toml:18", "must be a positive integer, got 1.5"], id="max-steps-float"),
    pytest.param(edit('coordinates = ["x"]', 'coordinates = ["__x"]'), ProblemFileError,
                 ["osc.toml:3", "starts with an underscore"], id="name-dunder"),
    pytest.param(edit('coordinates = ["x"]', 'coordinates = ["t"]'), ProblemFileError,
                 ["osc.toml:3", "reserved"], id="name-reserved"),
    pytest.param(edit('title = "bad-input test oscillator"', "title = [1]"), ProblemFileError,
                 ["osc.toml:2", "key 'title'", "must be a string"], id="title-not-string"),
]  # fmt: skip


def write_problem(folder, change, name="osc"):
    text = change(GOOD.replace('name = "osc"', f'name = "{name}"'))
    path = folder / f"{name}.toml"
    path.write_bytes(text.encode("utf-8", errors="surrogateescape"))
    return path


def test_the_good_file_loads_and_solves(tmp_path):
    problem = hamrkq.load_problem(write_problem(tmp_path, lambda s: s))
    sol = hamrkq.solve(problem, t_span=(0, 1))
    assert sol.success
    omega = 2.0  # sqrt(k/m)
    exact = np.column_stack([np.cos(omega * sol.t), -2 * omega * np.sin(omega * sol.t)])
    assert np.abs(sol.y - exact).max() <= 1.05e-8


@pytest.mark.parametrize(("change", "error", "fragments"), FILES)
def test_problem_files_are_refused_with_file_line_and_key(tmp_path, monkeypatch, change, error,
                                                          fragments):  # fmt: skip
    monkeypatch.chdir(tmp_path)
    path = write_problem(tmp_path, change)
    with pytest.raises(error) as info:
        hamrkq.load_problem(path)
    message = str(info.value)
    assert str(path) in message
    for fragment in fragments:
        assert fragment.replace("osc.toml", str(path)) in message, message
    assert info.value.path == str(path)
    assert sorted(item.name for item in tmp_path.iterdir()) == ["osc.toml"]  # nothing ran


# -- the command line --------------------------------------------------------------------
COLLISION = """\
name = "collision"
title = "falls into the singularity of -1/q at t = 0.37678"
coordinates = ["q"]
momenta = ["p"]
hamiltonian = "p**2/2 - 1/q"

[initial]
q = [1]
p = [-2]

[integration]
t_span = [0, 2]
atol = 1e-6
"""
DOMAIN_EDGE = COLLISION.replace("collision", "edge").replace("- 1/q", "+ 2*sqrt(q)")


@pytest.fixture
def files(tmp_path):
    folder = tmp_path / "files"
    folder.mkdir()
    (folder / "collision.toml").write_text(COLLISION)
    (folder / "edge.toml").write_text(DOMAIN_EDGE)
    write_problem(folder, edit("k*x**2/2", "exec('1')"))
    write_problem(folder, edit('method = "rk34q8"', 'method = "euler"'), name="badmethod")
    (folder / "not_a_dir").write_text("")
    return folder


QUICK = ["--no-plots", "--reference", "none"]

# (argv, with FILES/ the folder of the fixture; exit status; fragments of stderr)
CLI_BAD = [
    pytest.param(["run", "no_such_problem"], ["no problem named 'no_such_problem'"],
                 id="unknown-problem"),
    pytest.param(["run", "FILES/missing.toml"], ["missing.toml' does not exist"],
                 id="missing-file"),
    pytest.param(["run", "harmonic", "--method", "rk45"], ["method='rk45' is not valid"],
                 id="method"),
    pytest.param(["run", "harmonic", "--atol", "0"],
                 ["--atol '0': expected a positive finite number"], id="atol-zero"),
    pytest.param(["run", "harmonic", "--atol", "tiny"],
                 ["--atol 'tiny': expected a positive finite number or NAME=NUMBER"],
                 id="atol-not-a-number"),
    pytest.param(["run", "harmonic", "--rtol", "-1"], ["rtol must be finite and zero or positive"],
                 id="rtol-negative"),
    pytest.param(["run", "harmonic", "--t-end", "nan"], ["t_span must be finite"],
                 id="t-end-nan"),
    pytest.param(["run", "harmonic", "--max-steps", "0"],
                 ["max_steps must be a positive integer, got 0"], id="max-steps"),
    pytest.param(["run", "harmonic", "--atoll", "1"], ["unrecognized arguments: --atoll"],
                 id="unknown-option"),
    pytest.param(["run", "kepler", "--param", "e=1"],
                 ["key 'initial.p[1]'", "not a finite real number for the parameters e = 1"],
                 id="kepler-e=1"),
    pytest.param(["run", "kepler", "--param", "e=sin(1)"], ["expected NAME=NUMBER"],
                 id="param-expression"),
    pytest.param(["run", "FILES/osc.toml"], ["osc.toml:5", "function 'exec' is not allowed"],
                 id="hostile-file"),
    pytest.param(["show", "FILES/osc.toml"], ["osc.toml:5", "exec"], id="show-hostile-file"),
    pytest.param(["run", "FILES/badmethod.toml"],
                 ["badmethod.toml:18", "key 'integration.method'", "'euler' is not valid"],
                 id="file-method"),
    pytest.param(["run", "harmonic", "--out", "FILES/not_a_dir"],
                 ["exists and is not a directory"], id="out-is-a-file"),
    pytest.param([], ["the following arguments are required"], id="no-command"),
    pytest.param(["frobnicate"], ["invalid choice: 'frobnicate'"], id="unknown-command"),
]  # fmt: skip


def _argv(argv, folder):
    return [item.replace("FILES", str(folder)) for item in argv]


@pytest.mark.parametrize(("argv", "fragments"), CLI_BAD)
def test_cli_bad_input_exits_2_with_one_message(files, tmp_path, capsys, argv, fragments):
    out = tmp_path / "out"
    extra = [] if not argv or "--out" in argv or argv[0] != "run" else ["--out", str(out)]
    assert main(_argv(argv, files) + extra) == 2
    captured = capsys.readouterr()
    for fragment in fragments:
        assert fragment.replace("FILES", str(files)) in captured.err, captured.err
    assert "Traceback" not in captured.err + captured.out
    assert not out.exists()  # bad input writes nothing


# (argv, the status of the partial result, a fragment of its message)
CLI_FAILED = [
    pytest.param(["run", "harmonic", "--max-steps", "5"], Status.MAX_STEPS, "max_steps = 5",
                 id="max-steps"),
    pytest.param(["run", "FILES/collision.toml"], Status.TOLERANCE_UNATTAINABLE,
                 "can no longer be certified", id="singularity"),
    pytest.param(["run", "FILES/collision.toml", "--method", "rk34"], Status.STEP_SIZE_UNDERFLOW,
                 "fell below the roundoff floor", id="underflow"),
    pytest.param(["run", "FILES/edge.toml", "--method", "rk34"], Status.NON_FINITE,
                 "non-finite", id="non-finite"),
]  # fmt: skip


@pytest.mark.parametrize(("argv", "status", "fragment"), CLI_FAILED)
def test_cli_failed_run_exits_1_and_writes_partial_results(files, tmp_path, capsys, argv, status,
                                                           fragment):  # fmt: skip
    out = tmp_path / "out"
    assert main([*_argv(argv, files), *QUICK, "--out", str(out)]) == 1
    captured = capsys.readouterr()
    assert f"{status.name} (partial results)" in captured.out
    assert fragment in captured.out and "Traceback" not in captured.err + captured.out
    saved = Solution.load(out / "solution.npz")
    assert saved.status is status and saved.partial and len(saved) >= 2
    assert f"t = {float(saved.t[-1])!r}" in saved.message


@pytest.mark.slow
def test_the_process_itself_prints_no_traceback(files, tmp_path):
    """The same through ``python -m hamrkq``: exit status and stderr of the process."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    cases = [
        (["run", "kepler", "--param", "e=2"], 2, "not a finite real number"),
        (["show", f"{files}/osc.toml"], 2, "function 'exec' is not allowed"),
        (["run", "harmonic", "--max-steps", "3", *QUICK, "--out", str(tmp_path / "o")], 1, ""),
    ]
    for argv, status, fragment in cases:
        done = subprocess.run(
            [sys.executable, "-m", "hamrkq", *argv],
            capture_output=True,
            text=True,
            timeout=120,
            env=env,
            cwd=tmp_path,
        )
        assert done.returncode == status, done.stderr
        assert fragment in done.stderr and "Traceback" not in done.stderr
        if status == 2:
            assert done.stderr.count("\n") == 1 and done.stderr.startswith("hamrkq: error: ")
    assert math.isfinite(Solution.load(tmp_path / "o" / "solution.npz").t[-1])


def test_there_are_at_least_forty_bad_inputs():
    assert len(LIBRARY) + len(FILES) + len(CLI_BAD) + len(CLI_FAILED) >= 40
