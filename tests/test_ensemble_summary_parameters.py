"""``hamrkq ensemble``'s summary.json does not report a gridded parameter as
one value (found by QA: ``--grid e=0.1:0.99:6`` on kepler wrote
``"parameters": {"e": 0.6}``, the file's default, which no member ran): the
gridded parameter is listed under ``grid``, ``parameters`` holds the fixed
ones."""

from __future__ import annotations

import json

from helpers import oscillator_file, run_cli


def test_a_gridded_parameter_is_not_reported_as_a_single_value(tmp_path):
    path = oscillator_file(
        tmp_path / "duffing.toml",
        hamiltonian="p**2/2 + a*q**2/2 + b*q**4/4",
        extra="[parameters]\na = 1.5\nb = 0.25\n",
    )
    out = tmp_path / "out"
    status, _, err = run_cli("ensemble", path, "--grid", "a=0.5:2:3",
                             "--workers", "1", "--no-plots", "--out", out)  # fmt: skip
    assert status == 0, err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["grid"] == [{"name": "a", "lo": 0.5, "hi": 2.0, "n": 3}]
    assert summary["parameters"] == {"b": 0.25}
