"""``sol.sol(t)`` where a component's ``rtol`` tolerance dips to ``atol`` between nodes.

    python benchmarks/dense_zero_crossing.py

Kepler (e = 0.6, ten orbits) at ``rtol`` 1e-6, ``atol`` 1e-9, every node
kept, ``dense_output=True``: the largest true error over the tolerance
``max(atol, rtol |y_exact|)`` of ``sol.sol`` at the pericentre times
``2 pi k`` (where ``p1 = 0``) and at 2001 equally spaced times, and at the
nodes, for several methods, against the exact solution.  Output times of
``t_eval`` get the quencher's check at the value; ``sol.sol`` does not
(docs/events.md).  Writes ``dense_zero_crossing.txt`` beside this file.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

import hamrkq

HERE = Path(__file__).resolve().parent
METHODS = ("auto", "rk34q8", "rk78q12", "rk67q10")


def ratio(values: np.ndarray, exact: np.ndarray) -> np.ndarray:
    return np.abs(values - exact) / np.maximum(1e-9, 1e-6 * np.abs(exact))


def main() -> None:
    warnings.simplefilter("ignore")
    kepler = hamrkq.load_problem("kepler")
    lines = [
        "Kepler e = 0.6 at rtol 1e-6, atol 1e-9, every node kept: the largest true error",
        "over the tolerance of sol.sol at the pericentres (p1 = 0) and at 2001 times, and",
        "at the nodes.",
        "",
        f"{'method':<10} {'status':<24} {'t reached':>10} {'pericentres':>12} "
        f"{'2001 times':>11} {'nodes':>7}",
    ]
    for method in METHODS:
        sol = hamrkq.solve(kepler, method=method, atol=1e-9, rtol=1e-6, dense_output=True)
        end = sol.t[-1]
        peri = np.array([2 * np.pi * k for k in range(1, 11) if 2 * np.pi * k <= end])
        grid = np.linspace(0.0, end, 2001)
        at_peri = ratio(sol.sol.values(peri), kepler.exact(peri)).max() if peri.size else np.nan
        at_grid = ratio(sol.sol.values(grid), kepler.exact(grid)).max()
        at_nodes = ratio(sol.y, kepler.exact(sol.t)).max()
        lines.append(
            f"{method:<10} {sol.status.name:<24} {end:>10.4g} {at_peri:>12.3f} "
            f"{at_grid:>11.3f} {at_nodes:>7.3f}"
        )
    text = "\n".join(lines) + "\n"
    (HERE / "dense_zero_crossing.txt").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
