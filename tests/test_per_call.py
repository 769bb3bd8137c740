"""What a call of ``solve`` computes once and remembers: the same results as
computing it again (issue #13, the per-call overhead of a tiny problem)."""

from __future__ import annotations

import gc

import numpy as np
import pytest

import hamrkq
from hamrkq import result
from hamrkq.errors import InputError, InputTypeError
from hamrkq.options import SolveOptions
from hamrkq.rkq.config import Settings
from hamrkq.rkq.driver import Integration, python_functions
from hamrkq.rkq.family import get_member
from hamrkq.rkq.layout import new_state


def test_remembered_options_are_the_options_checked_again():
    given = {"method": "rk34q8", "safety": 0.8, "keep_every": 1}
    first = SolveOptions.resolve(given, {})
    assert SolveOptions.resolve(dict(given), {}) is first
    assert first == SolveOptions._resolve(given, {})
    # equal keys of a dict, not the same option: True is no count
    with pytest.raises(InputError, match="keep_every"):
        SolveOptions.resolve({**given, "keep_every": True}, {})
    # a problem's setting under the keyword's
    assert SolveOptions.resolve({"method": "rk34q8"}, {"safety": 0.5}).safety == 0.5
    assert SolveOptions.resolve({"method": "rk34q8", "safety": 0.7}, {"safety": 0.5}).safety == 0.7


def test_an_unhashable_option_is_checked_without_the_memo():
    with pytest.raises(InputTypeError, match="safety"):
        SolveOptions.resolve({"method": "rk34q8", "safety": [0.5]}, {})


def test_auto_options_copied_once_per_member():
    options = SolveOptions.resolve({"method": "auto"}, {})
    chosen = options.with_auto(2, 1e-8)
    assert chosen.method != "auto" and chosen.z_substeps is not None
    assert options.with_auto(2, 1e-8) is chosen


@pytest.mark.parametrize("t0", [0.0, -3.5, 1e8])
def test_a_runs_state_record_is_new_states(t0):
    member = get_member("rk34q8")

    def f(t, y, params, out):
        out[:] = y

    run = Integration(
        python_functions(f, f), member, np.zeros(0), t0, np.ones(2), t0 + 1.0,
        np.full(2, 1e-6), np.zeros(2), Settings(quench=0, rule=0, gamma=0),
    )  # fmt: skip
    expected = new_state(t0)
    assert run.state.dtype == expected.dtype and run.state.shape == expected.shape
    assert run.state.tobytes() == expected.tobytes()
    assert run.state.flags.c_contiguous and run.state.flags.writeable


def test_a_dead_solutions_arrays_leave_the_registry():
    sol = hamrkq.solve(hamrkq.load_problem("harmonic"), t_span=(0.0, 0.1), method="rk34q8")
    kept = len(result._KEPT)
    ids = [id(sol.t), id(sol.y)]
    assert all(i in result._KEPT for i in ids)
    del sol
    gc.collect()
    assert len(result._KEPT) < kept
    assert not any(i in result._KEPT and result._KEPT[i]() is not None for i in ids)


def test_a_configuration_record_is_numpys_record_of_the_values():
    from hamrkq.rkq.layout import CONFIG, new_config

    for k, special in enumerate((0.0, -0.0, np.inf, np.nan, 1e-310, np.float64(2.5), 7, 3.9)):
        values = {
            name: (k if CONFIG.fields[name][0].kind == "i" else special) for name in CONFIG.names
        }
        values["keep_every"] = special if isinstance(special, int) else 2  # a float truncates
        expected = np.array([tuple(values[name] for name in CONFIG.names)], dtype=CONFIG)
        made = new_config(**values)
        assert made.tobytes() == expected.tobytes() and made.shape == (1,)
        assert made.flags.writeable and made.flags.aligned and made.flags.c_contiguous
    values["keep_every"] = 2.7  # struct refuses it: NumPy's conversion, as before
    assert new_config(**values)[0]["keep_every"] == 2
    with pytest.raises(TypeError, match="missing"):
        new_config(**{k: v for k, v in values.items() if k != "beta"})
    with pytest.raises(TypeError, match="unknown"):
        new_config(**values, bogus=1.0)


@pytest.mark.parametrize("method", ["rk34q8", "rk78q12", "rk34"])
def test_a_runs_output_record_is_the_dataclass_s_own(method):
    """A run's RunOutput is made without the frozen dataclass's __init__:
    the same fields in the same order as ``dataclasses.replace`` (which
    calls it) makes of it, every field given or defaulted."""
    import dataclasses

    from hamrkq.solve import prepare
    from hamrkq.solve.dispatch import integration

    task = prepare(hamrkq.load_problem("harmonic"), t_span=(0.0, 0.5), method=method).task
    out = integration(task, "python").run()
    again = dataclasses.replace(out)
    assert list(vars(out)) == list(vars(again)) == [f.name for f in dataclasses.fields(out)]
    assert all(getattr(out, name) is getattr(again, name) for name in vars(again))
    assert not any(value is dataclasses.MISSING for value in vars(out).values())
    with pytest.raises(dataclasses.FrozenInstanceError):
        out.status = 0


@pytest.mark.parametrize("t0, t_end", [(0.0, 1.0), (-0.0, -2.5), (1e8, 1e8 + 3.0), (0.0, np.inf)])
def test_a_runs_remembered_configuration_is_the_record_of_its_fields(t0, t_end):
    """The kernel's configuration is made once per member and settings and
    copied with the run's t0 and t_end: the bytes of the record made from
    the fields, for settings met before or not, with a float in an integer
    field (NumPy truncates it) and with a zero whose sign the key cannot
    tell apart."""
    from hamrkq.rkq import config

    for name in ("rk34q8", "rk78q12"):
        member = get_member(name)
        for settings in (
            Settings(quench=0, rule=0, gamma=1),
            Settings(quench=1, rule=1, gamma=2, keep_every=2.7, first_step=0.01, witness=True),
            Settings(quench=0, rule=0, gamma=1, first_step=-0.0),
        ):
            expected = config.kernel_config(
                member, settings, settings.gamma, 0, 1, t0, t_end, False
            )
            for _ in range(2):  # made, then remembered
                made = config.kernel_config(member, settings, settings.gamma, 0, 1, t0, t_end)
                assert made.tobytes() == expected.tobytes() and made.dtype == expected.dtype
                assert made.flags.writeable and made.flags.aligned and made.flags.c_contiguous


def test_every_setting_but_the_times_is_in_a_remembered_configurations_key():
    """Changing any one field of Settings after a run remembered its
    configuration gives the record made afresh from the changed fields:
    the key is every field (but ``t_eval``, passed apart), so a field added
    to Settings cannot be left out of it."""
    import dataclasses

    from hamrkq.rkq import config

    member = get_member("rk78q12")
    base = Settings(quench=0, rule=0, gamma=3)
    changed = {"quench": 1, "rule": 1, "gamma": 2, "safety": 0.8, "theta": 0.5,
               "max_step": 2.0, "max_steps": 7, "gamma_limit": 0.01, "keep_every": 3,
               "first_step": 0.125, "witness": True, "project": True,
               "double_double": True, "dense_share": 0.25}  # fmt: skip
    keyed = {f.name for f in dataclasses.fields(Settings)} - {"t_eval"}
    assert set(changed) == keyed
    config.kernel_config(member, base, base.gamma, 0, 1, 0.0, 1.0)
    for name, value in changed.items():
        settings = dataclasses.replace(base, **{name: value})
        expected = config.kernel_config(member, settings, base.gamma, 0, 1, 0.0, 1.0, False)
        for _ in range(2):  # made, then remembered
            made = config.kernel_config(member, settings, base.gamma, 0, 1, 0.0, 1.0)
            assert made.tobytes() == expected.tobytes(), name


def test_one_small_state_s_rules_on_floats_give_the_hand_computed_decisions():
    """A run's rules after it, for one state, on Python floats (every solve
    asks them: 18 us each on arrays): the hand-computed decisions of
    ``tests/test_ensemble_rules.py``, and the same for a state too large
    for floats (each component repeated three times: the same halves, so the
    same decisions), which the whole-array rules decide."""
    from test_ensemble_rules import AFTER_A_RUN

    from hamrkq.rkq import scales
    from hamrkq.rkq import witness_rules as wr

    for (y0, size, atol, rtol, steps, step_range), after, outgrew in AFTER_A_RUN:
        for copies in (1, 3):
            state, sizes = (np.repeat(np.array(v, dtype=float), copies) for v in (y0, size))
            floor, relative = (np.broadcast_to(v, (4,)).repeat(copies) for v in (atol, rtol))
            assert (state.size <= scales.SMALL_STATE) == (copies == 1)
            decided = wr.needs_witness_after_run(floor, relative, state, steps, sizes, step_range)
            assert decided is after, (y0, size, atol, copies)
            if steps == wr.WITNESS_REFERENCE_STEPS and step_range == 1.0:
                grown = wr.state_outgrew_its_start(floor, relative, state, sizes)
                assert grown is outgrew, (y0, size, atol, copies)
                # one state through the per-row rule: a NumPy bool, as before
                grown = wr.state_outgrew_its_start_per_row(floor, relative, state, sizes)
                assert type(grown) is np.bool_ and grown == outgrew


def test_a_solutions_run_arrays_are_its_own_and_read_only():
    problem = hamrkq.load_problem("harmonic")
    sol = hamrkq.solve(problem, t_span=(0.0, 0.1), method="rk34q8")
    again = hamrkq.solve(problem, t_span=(0.0, 0.1), method="rk34q8")
    for name in ("t", "y", "z", "global_error", "gamma", "energy", "quenched", "atol", "rtol"):
        array = getattr(sol, name)
        assert not array.flags.writeable and array.base is None
        assert array.tobytes() == getattr(again, name).tobytes()
        assert not np.shares_memory(array, getattr(again, name))
    assert sol.quenched.dtype == bool
    # an array a caller holds is still copied
    y = np.array(sol.y)
    assert result.owned(y[1:]).flags.writeable and y.flags.writeable  # a view: left as it is
    assert sol.replace(y=y).y is not y
