"""hamrkq compare: the promised files, the numbers in them, and how headline runs are chosen."""

from __future__ import annotations

import contextlib
import csv
import io
import json
import math

import numpy as np
import pytest

import hamrkq
from hamrkq.analysis.comparison import compare, default_methods
from hamrkq.cli import main
from hamrkq.cli.compare import FILES

ONE_PERIOD = 2 * np.pi
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def run_cli(argv):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = main(argv)
    return status, out.getvalue(), err.getvalue()


@pytest.fixture(scope="module")
def kepler_compare(tmp_path_factory):
    out = tmp_path_factory.mktemp("compare") / "kepler"
    status, stdout, stderr = run_cli(
        ["compare", "kepler", "--t-end", repr(ONE_PERIOD), "--quick", "--out", str(out)]
    )
    return status, stdout, stderr, out


def test_compare_writes_every_promised_file(kepler_compare):
    status, stdout, stderr, out = kepler_compare
    assert status == 0, stderr
    assert sorted(p.name for p in out.iterdir()) == sorted(FILES.values())
    listed = json.loads((out / FILES["json"]).read_text())["files"]
    assert sorted(listed) == sorted(FILES.values())
    for name in (FILES["work_precision"], FILES["energy"]):
        data = (out / name).read_bytes()
        assert data.startswith(PNG_MAGIC) and len(data) > 10_000
    assert "matched error" in stdout and "wrote" in stdout


def test_comparison_json_lists_only_the_files_written(tmp_path):
    """With --no-plots it listed the two figures it had not written (QA)."""
    out = tmp_path / "cmp"
    argv = ["compare", "harmonic", "--methods", "rk34q8", "--quick", "--t-end", "2"]
    status, _, stderr = run_cli([*argv, "--no-plots", "--out", str(out)])
    assert status == 0, stderr
    listed = json.loads((out / FILES["json"]).read_text())["files"]
    assert sorted(listed) == sorted(p.name for p in out.iterdir())
    assert FILES["work_precision"] not in listed


def test_tables_agree_and_hold_every_column(kepler_compare):
    _, _, _, out = kepler_compare
    data = json.loads((out / FILES["json"]).read_text())
    with open(out / FILES["csv"], newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == len(data["runs"])
    # rk34q8 (anchor), auto, rk34, DOP853, gauss4, gauss6, yoshida4: 3 settings each
    methods = [r["method"] for r in data["runs"]]
    assert methods.count("rk34q8") == 3 and len(methods) >= 18  # + refinements
    assert set(methods) == set(default_methods(hamrkq.load_problem("kepler")))
    for key in ("method", "settings", "steps", "nfev", "wall_time_s", "max_true_error",
                "max_abs_energy_error", "drift_slope", "status", "selected"):  # fmt: skip
        assert key in rows[0] and key in data["runs"][0]
    for row, run in zip(rows, data["runs"], strict=True):
        assert row["method"] == run["method"] and int(row["nfev"]) == run["nfev"]
        assert float(row["max_true_error"]) == pytest.approx(run["max_true_error"], rel=1e-15)
    assert sum(r["selected"] for r in data["runs"]) == len(set(methods))
    md = (out / FILES["markdown"]).read_text()
    assert "matched error" in md and "## Headline" in md and "exact solution" in md
    assert md.count("| rk34q8 |") == 1 + 3  # headline + sweep
    assert "hamrkq compare kepler --methods" in md


def test_true_errors_are_those_of_an_independent_recomputation(kepler_compare):
    """Re-run two settings of the JSON with hamrkq.solve and measure against the exact orbit."""
    _, _, _, out = kepler_compare
    data = json.loads((out / FILES["json"]).read_text())
    problem = hamrkq.load_problem("kepler")
    span = (0.0, ONE_PERIOD)
    anchor = next(r for r in data["runs"] if r["method"] == "rk34q8" and r["factor"] == 1.0)
    sol = hamrkq.solve(problem, method="rk34q8", t_span=span)
    assert anchor["nfev"] == sol.nfev
    assert anchor["max_true_error"] == pytest.approx(
        np.abs(sol.y - problem.exact(sol.t)).max(), rel=1e-12
    )
    # RKQ's promise: the true error stays within the tolerance (atol 1e-8 for kepler).
    assert 0.5e-8 < anchor["max_true_error"] <= 1.0e-8
    dop = next(r for r in data["runs"] if r["method"] == "scipy:DOP853" and r["factor"] == 1e-2)
    sol = hamrkq.solve(problem, method="scipy:DOP853", t_span=span, atol=1e-10, rtol=0.0)
    assert dop["steps"] == sol.stats["steps"]
    assert dop["max_true_error"] == pytest.approx(
        np.abs(sol.y - problem.exact(sol.t)).max(), rel=1e-12
    )
    energy = np.abs(sol.energy - sol.energy[0]).max()
    assert dop["max_abs_energy_error"] == pytest.approx(energy, rel=1e-12)


def test_matched_error_picks_the_cheapest_run_within_the_target(kepler_compare):
    _, _, _, out = kepler_compare
    data = json.loads((out / FILES["json"]).read_text())
    target = data["target"]
    for method in {r["method"] for r in data["runs"]}:
        own = [r for r in data["runs"] if r["method"] == method and r["status"] == "SUCCESS"]
        (chosen,) = [r for r in own if r["selected"]]
        good = [r for r in own if r["max_true_error"] <= target]
        if good:
            assert chosen["nfev"] == min(r["nfev"] for r in good)
        else:
            assert chosen["max_true_error"] == min(r["max_true_error"] for r in own)
            assert any(method in note for note in data["notes"])


def test_refinement_brings_every_headline_error_near_the_target(kepler_compare):
    """Interpolated or extrapolated settings: every method's headline run is within
    [0.3, 1] x the anchor's error (measured 0.57-0.80 x), not orders of magnitude
    more accurate than it needs to be."""
    _, _, _, out = kepler_compare
    data = json.loads((out / FILES["json"]).read_text())
    target = data["target"]
    chosen = [r for r in data["runs"] if r["selected"] and r["method"] != "rk34q8"]
    assert len(chosen) == 6
    for run in chosen:
        assert 0.3 * target <= run["max_true_error"] <= target, run
    # the refinements are extra rows beyond the three settings per method
    assert len(data["runs"]) > 18


def test_matched_cost_and_the_step_sweep():
    problem = hamrkq.load_problem("kepler")
    result = compare(problem, ["scipy:DOP853", "yoshida4"], t_end=ONE_PERIOD / 2,
                     quick=True, match="cost")  # fmt: skip
    assert result.runs[0].method == "rk34q8"  # the anchor is added first
    target = result.anchor.nfev
    assert result.target == target and "matched cost" in result.matched_by()
    for method in ("scipy:DOP853", "yoshida4"):
        own = [r for r in result.runs if r.method == method]
        (chosen,) = [r for r in own if r.selected]
        ratio = lambda r: abs(math.log(r.nfev / target))  # noqa: E731
        assert ratio(chosen) == min(ratio(r) for r in own)
    # h_ref spends the anchor's evaluations: yoshida4 costs 6 f per step.
    steps = {r.factor: r.settings["step"] for r in result.runs if r.method == "yoshida4"}
    h_ref = steps[2.0] / 2.0
    assert h_ref == pytest.approx(ONE_PERIOD / 2 * 6 / target, rel=0.01)
    yoshida = next(r for r in result.runs if r.method == "yoshida4" and r.factor == 0.5)
    assert yoshida.nfev == pytest.approx(2 * target, rel=0.02)


def test_bad_input_exits_2(tmp_path):
    status, _, err = run_cli(["compare", "kepler", "--methods", "euler", "--out",
                              str(tmp_path / "a")])  # fmt: skip
    assert status == 2 and "euler" in err
    status, _, err = run_cli(["compare", "prentice2011", "--methods", "verlet", "--quick",
                              "--out", str(tmp_path / "b")])  # fmt: skip
    assert status == 2 and "separable" in err
    busy = tmp_path / "busy"
    busy.mkdir()
    (busy / "mine.txt").write_text("keep")
    status, _, err = run_cli(["compare", "kepler", "--out", str(busy)])
    assert status == 2 and "--force" in err
    status, _, err = run_cli(["compare", "kepler", "--t-end", "0", "--out",
                              str(tmp_path / "c")])  # fmt: skip
    assert status == 2 and "empty" in err


def test_non_separable_default_drops_splitting_methods():
    prentice = hamrkq.load_problem("prentice2011")
    methods = default_methods(prentice)
    assert "yoshida4" not in methods and "gauss4" in methods and methods[0] == "rk34q8"


def test_compare_compiles_before_it_times_a_run(monkeypatch):
    # A first use must not be timed: neither the compiler nor, compiling in
    # the background, the interpreted loop (docs/performance.md).
    from hamrkq.analysis import comparison
    from hamrkq.backends import first_use

    events, resolve, timed = [], first_use.resolve_backend, comparison._timed

    def resolving(backend, ham=None, gamma="tangent"):
        events.append("compile")
        return resolve(backend, ham, gamma)

    def timing(*args):
        events.append("run")
        return timed(*args)

    monkeypatch.setattr(first_use, "resolve_backend", resolving)
    monkeypatch.setattr(comparison, "_timed", timing)
    compare(hamrkq.load_problem("kepler"), ["scipy:DOP853"], t_end=ONE_PERIOD / 4, quick=True)
    assert events[0] == "compile" and "run" in events  # (each solve asks again: cheap)


def test_each_method_runs_once_untimed_before_its_sweep(monkeypatch):
    # What a method's first call pays once (SciPy's numerical functions,
    # the kernel's first signature) must not land in its first timed run.
    from hamrkq.analysis import comparison

    spans, timed = [], comparison._timed

    def timing(problem, method, t_span, *rest):
        spans.append((method, t_span[1] - t_span[0]))
        return timed(problem, method, t_span, *rest)

    monkeypatch.setattr(comparison, "_timed", timing)
    end = ONE_PERIOD / 4
    result = compare(hamrkq.load_problem("kepler"), ["scipy:DOP853", "gauss4"], t_end=end,
                     quick=True)  # fmt: skip
    for method in ("rk34q8", "scipy:DOP853", "gauss4"):
        first = next(length for m, length in spans if m == method)
        assert first == pytest.approx(end * 1e-3)  # the untimed warm-up
    # ... and the timed runs are the whole interval
    assert all(r.solution.t[-1] == pytest.approx(end) for r in result.runs)


def test_auto_and_family_members_are_compared_as_rkq():
    # auto and the family's members bound the global error like rk34q8: they
    # get its sweep (no extrapolated runs), and auto's rows name its member.
    problem = hamrkq.load_problem("kepler")
    result = compare(problem, ["auto", "rk78q12"], t_end=ONE_PERIOD / 2, quick=True)
    auto = [r for r in result.runs if r.method == "auto"]
    member = [r for r in result.runs if r.method == "rk78q12"]
    assert sorted(r.factor for r in auto) == sorted(r.factor for r in member) == [0.1, 1.0, 10.0]
    by_factor = lambda r: r.factor  # noqa: E731
    for a, m in zip(sorted(auto, key=by_factor), sorted(member, key=by_factor), strict=True):
        assert a.solution.method == "rk78q12" and a.nfev == m.nfev
        assert a.max_error <= 1.05 * a.solution.atol.max()
    assert {(r.row()["method"], r.row()["ran"]) for r in auto} == {("auto", "rk78q12")}


def test_a_runs_cost_counts_the_runs_auto_discarded():
    from hamrkq.analysis.comparison_runs import Run

    sol = hamrkq.solve(hamrkq.load_problem("kepler"), t_span=(0, 1), method="auto")
    stats = {**sol.stats, "discarded_evaluations": 1234}
    run = Run("auto", 1.0, {}, sol.replace(stats=stats), 0.0)
    assert run.nfev == sol.nfev + 1234
