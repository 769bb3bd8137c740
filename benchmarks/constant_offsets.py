"""Constant offsets in the generated code, measured on the Arenstorf orbit.

    python benchmarks/constant_offsets.py

The generated right-hand side adds the constant part of a sum such as
``q1 + mu - 1`` as a double-double (``hamrkq.backends.scalar_printer``,
``OffsetSum``).  Rounded to one double, ``mu`` loses its low bits the same
way at every evaluation in a binade of ``q1``, which displaces the Moon by up
to half an ulp of 1: a systematic force error, magnified by the cancellation
near the Moon, that every run on the same code shares (the rounding witness
included).  This script measures, with and without the offsets (the second
in a fresh process and cache, the offsets switched off):

1. the quencher's error (``y - global_error``) against the long-double
   reference with exact arithmetic on the parameters' doubles, for
   ``rk78q12`` with 2 and 4 quencher steps a step at ``atol`` 1e-10 and no
   limit on Gamma: the error that does not depend on the mesh;
2. ``method="auto"`` with its quencher in double at ``atol`` 1e-10 and
   1e-12: status, where it ended, and the largest true error over the
   tolerance on 201 times (the check of ``benchmarks/promise.py``);

and how far the reference with the parameters folded into 53-bit SymPy
Floats (how the references were made before) is from the exact one.
Writes ``benchmarks/constant_offsets.txt``.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import warnings
from pathlib import Path

import extended_reference
import numpy as np

import hamrkq

HERE = Path(__file__).resolve().parent
NODES = 201
WITHOUT = "--without-offsets"


def measurements() -> dict:
    """Both measurements, in this process's code generator."""
    warnings.simplefilter("ignore")
    problem = hamrkq.load_problem("arenstorf")
    grid = np.linspace(*problem.t_span, NODES)
    truth = extended_reference.reference(problem, grid)
    result: dict = {"quencher": {}, "auto": {}}
    for substeps in (2, 4):
        sol = hamrkq.solve(
            problem, method="rk78q12", atol=1e-10, rtol=0.0, z_substeps=substeps,
            gamma_limit=1e30, t_eval=grid,
        )  # fmt: skip
        z = sol.y - sol.global_error
        error = np.abs(z - truth[: sol.t.size]).max(axis=1)
        result["quencher"][substeps] = {"end": float(error[-1]), "max": float(error.max())}
    for atol in (1e-10, 1e-12):
        # In double: in double-double, f's sums are exact either way.
        sol = hamrkq.solve(
            problem, method="auto", atol=atol, rtol=0.0, t_eval=grid, quencher_precision="double"
        )
        error = np.abs(sol.y - truth[: sol.t.size]).max() / atol
        result["auto"][f"{atol:g}"] = {
            "status": sol.status.name,
            "t_last": float(sol.t[-1]),
            "max_error_over_tol": float(error),
        }
    return result


def without_offsets() -> dict:
    """The measurements in a fresh process whose code generator adds
    constants in one double, with its own empty cache."""
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, HAMRKQ_CACHE_DIR=cache)
        out = subprocess.run(
            [sys.executable, __file__, WITHOUT], env=env, check=True, capture_output=True,
            text=True,
        )  # fmt: skip
    return json.loads(out.stdout.splitlines()[-1])


def main() -> None:
    if WITHOUT in sys.argv:
        from hamrkq.backends import scalar_printer

        scalar_printer._constant_offsets = lambda exprs, parameters, temps: (list(exprs), [])
        print(json.dumps(measurements()))
        return
    problem = hamrkq.load_problem("arenstorf")
    grid = np.linspace(*problem.t_span, NODES)
    exact = extended_reference.reference(problem, grid)
    folded = extended_reference.reference(problem, grid, fold_parameters=True)
    runs = {"with offsets": measurements(), "without offsets": without_offsets()}
    lines = [
        "arenstorf over one period (t_end = 17.0652), 201 times.",
        "Reference (heyoka, long double, tol 1e-19) with the parameters' doubles in exact",
        f"arithmetic against the same with them folded into 53-bit SymPy Floats: max "
        f"{np.abs(exact - folded).max():.2e}, at t_end {np.abs(exact - folded)[-1].max():.2e}.",
        "",
        "Quencher error (max over components of |y - global_error - reference|),",
        "rk78q12, atol 1e-10, gamma_limit 1e30:",
    ]
    for label, run in runs.items():
        for substeps, error in run["quencher"].items():
            lines.append(
                f"  {label}, {substeps} quencher steps: at t_end {error['end']:.2e}, "
                f"max {error['max']:.2e}"
            )
    lines += ["", 'method="auto", quencher in double (status, t reached, max true error / atol):']
    for label, run in runs.items():
        for atol, info in run["auto"].items():
            lines.append(
                f"  {label}, atol {atol}: {info['status']}, t = {info['t_last']:.4f}, "
                f"{info['max_error_over_tol']:.3f}"
            )
    text = "\n".join(lines) + "\n"
    print(text, end="")
    (HERE / "constant_offsets.txt").write_text(text)


if __name__ == "__main__":
    main()
