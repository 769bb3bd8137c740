"""EnsembleSolution is frozen, pickles and round-trips through NPZ bit for bit;
a foreign or damaged file raises ResultFileError.  hamrkq.Hamiltonian pickles
(an ensemble ships it to other processes) even after its lambdified functions exist."""

from __future__ import annotations

import pickle
import zipfile

import numpy as np
import pytest
import sympy as sp

import hamrkq
from hamrkq.backends.numeric import numeric_of
from hamrkq.ensemble.result import FILE_FORMAT_VERSION
from hamrkq.errors import ResultFileError

q, p = sp.symbols("q p")


@pytest.fixture(scope="module")
def ens():
    # Two members fall into the 1/q singularity: the file must keep failures too.
    ham = hamrkq.Hamiltonian(p**2 / 2 - 1 / q, q=[q], p=[p])
    return hamrkq.ensemble(
        ham, q0=[1.0], p0=[[0.0], [2.0], [0.1]], t_span=(0, 2), t_eval=[0.5, 1.0, 2.0],
        atol=1e-8, workers=1,
    )  # fmt: skip


def _assert_same(a, b):
    for name in ("t", "y", "y0", "t_last", "status", "max_global_error", "energy0", "energy_drift",
                 "failed"):  # fmt: skip
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
        assert getattr(a, name).dtype == getattr(b, name).dtype
    assert a.messages == b.messages and a.names == b.names and a.method == b.method
    assert a.t_span == b.t_span and dict(a.options) == dict(b.options)
    assert a.stats.keys() == b.stats.keys() and a.parameters.keys() == b.parameters.keys()
    for k in a.stats:
        np.testing.assert_array_equal(a.stats[k], b.stats[k])


def test_the_fixture_has_failed_and_unreached_times(ens):
    assert ens.failed.tolist() == [0, 2]
    assert np.isnan(ens.y[0, 2]).all() and np.isfinite(ens.y[1]).all()
    # t_eval does not hold t0: H(y0) is evaluated apart, H = p0**2/2 - 1/q0.
    np.testing.assert_allclose(ens.energy0, [-1.0, 1.0, 0.005 - 1.0], rtol=0, atol=1e-15)


def test_arrays_are_read_only_and_fields_frozen(ens):
    for name in ("t", "y", "y0", "status", "energy_drift"):
        with pytest.raises(ValueError, match="read-only"):
            getattr(ens, name)[...] = 0
    with pytest.raises(ValueError, match="read-only"):
        ens.stats["nfev"][0] = 0
    with pytest.raises(TypeError):
        ens.stats["x"] = 1
    with pytest.raises(AttributeError):
        ens.y = None


def test_pickle_round_trip(ens):
    back = pickle.loads(pickle.dumps(ens))
    _assert_same(ens, back)
    assert not back.y.flags.writeable and not back.stats["nfev"].flags.writeable


def test_npz_round_trip_bitwise(ens, tmp_path):
    path = ens.save(tmp_path / "run")
    assert path.name == "run.npz"
    back = hamrkq.EnsembleSolution.load(path)
    _assert_same(ens, back)
    assert back.message(0) == ens.message(0)


def test_the_file_loads_without_pickle(ens, tmp_path):
    path = ens.save(tmp_path / "run.npz")
    with np.load(path, allow_pickle=False) as data:
        assert all(data[name].dtype != object for name in data.files)


def test_a_foreign_npz_is_refused(tmp_path):
    path = tmp_path / "foreign.npz"
    np.savez(path, y=np.zeros(3))
    with pytest.raises(ResultFileError, match="not a hamrkq ensemble file"):
        hamrkq.EnsembleSolution.load(path)
    sol = hamrkq.solve(hamrkq.load_problem("harmonic"), t_span=(0, 1))
    with pytest.raises(ResultFileError, match="not a hamrkq ensemble file"):
        hamrkq.EnsembleSolution.load(sol.save(tmp_path / "solution.npz"))


def test_a_newer_format_is_refused(ens, tmp_path):
    path = ens.save(tmp_path / "run.npz")
    with np.load(path) as data:
        arrays = {k: data[k] for k in data.files}
    arrays["meta"] = np.array(
        str(arrays["meta"]).replace(
            f'"format_version": {FILE_FORMAT_VERSION}',
            f'"format_version": {FILE_FORMAT_VERSION + 1}',
        )
    )
    np.savez(path, **arrays)
    with pytest.raises(ResultFileError, match="version 2 is not supported"):
        hamrkq.EnsembleSolution.load(path)


@pytest.mark.parametrize("damage", ["truncate", "garbage", "drop_member", "missing"])
def test_damaged_files_raise_result_file_error(ens, tmp_path, damage):
    path = ens.save(tmp_path / "run.npz")
    raw = path.read_bytes()
    if damage == "truncate":
        path.write_bytes(raw[: len(raw) // 2])
    elif damage == "garbage":
        path.write_bytes(b"not a zip file at all" * 10)
    elif damage == "drop_member":
        with zipfile.ZipFile(path) as src, zipfile.ZipFile(tmp_path / "x.npz", "w") as dst:
            for item in src.infolist():
                if item.filename != "energy_drift.npy":
                    dst.writestr(item, src.read(item.filename))
        path = tmp_path / "x.npz"
    else:
        path = tmp_path / "nothing.npz"
    with pytest.raises(ResultFileError, match=str(path.name)):
        hamrkq.EnsembleSolution.load(path)


def test_inconsistent_arrays_are_refused(ens):
    values = ens._fields()
    values["energy_drift"] = values["energy_drift"][:2]
    with pytest.raises(ValueError, match="energy_drift"):
        hamrkq.EnsembleSolution(**values)


def test_hamiltonian_pickles_after_its_numeric_functions_exist():
    a, b = sp.symbols("a b")
    ham = hamrkq.Hamiltonian(
        p**2 / 2 + a * q**4 + b * q, q=[q], p=[p], parameters={a: 0.25, b: None}, name="quartic"
    )
    numeric = numeric_of(ham)  # lambdified functions, cached on the object: they do not pickle
    back = pickle.loads(pickle.dumps(ham))
    assert back == ham and back.name == "quartic" and back.defaults == {a: 0.25}
    assert back.parameters == (a, b)
    y, params = np.array([[0.3, -0.2]]), np.array([0.25, 2.0])
    np.testing.assert_array_equal(
        numeric_of(back).energy(np.zeros(1), y, params), numeric.energy(np.zeros(1), y, params)
    )
    with pytest.raises(hamrkq.errors.InputError, match="no value for parameter"):
        back.parameter_values()


def test_a_success_that_nothing_certified_says_so_saved_or_not(tmp_path):
    """A member's message with gamma_limit=inf (or the estimate off) says,
    as hamrkq.solve's does, that nothing certified the tolerance (it said
    only that the member reached the end); the same after a file round trip,
    and not for a certified run."""
    oscillator = hamrkq.load_problem("harmonic")
    start = dict(q0=[[1.0]], p0=[[0.0]], t_span=(0.0, 10.0), atol=1e-8, workers=1)
    unchecked = hamrkq.ensemble(oscillator, gamma_limit=np.inf, **start)
    single = hamrkq.solve(oscillator, [1.0], [0.0], (0.0, 10.0), atol=1e-8, gamma_limit=np.inf)
    assert unchecked.message(0) == single.message
    assert "Nothing certified the tolerance: gamma_limit=inf" in unchecked.message(0)
    loaded = hamrkq.EnsembleSolution.load(unchecked.save(tmp_path / "unchecked"))
    assert loaded.message(0) == unchecked.message(0)
    off = hamrkq.ensemble(oscillator, method="rk45q8", global_error_estimate="off", **start)
    assert "global_error_estimate='off' leaves" in off.message(0)
    certified = hamrkq.ensemble(oscillator, **start)
    assert certified.message(0) == "The integration reached the end of the interval (t = 10.0)."
