"""Print the table of the RKQ family's tableaus for docs/algorithm.md.

Usage: ``python benchmarks/tableaus.py``.  Every number comes from the
tableau objects in :mod:`hamrkq.methods.registry` and one measurement:

- the largest coupling coefficient ``max |a_ij|`` and weight ``max |b_i|``;
- the float64 error floor: the smallest error, over n = 64 ... 4096 equal
  steps, after one period of a Kepler orbit (eccentricity 0.05, exact solution
  = initial value), integrated with the tableau's float arrays.  For the
  high-order methods this is rounding, which large coefficients amplify; for
  the low orders it is still truncation at n = 4096.

The order-condition proofs are in ``tests/test_tableaus_high_order.py``.
"""

from __future__ import annotations

import numpy as np

from hamrkq.methods.registry import ALL_TABLEAUS, PAIRS, QUENCHERS

ECCENTRICITY = 0.05
STEPS = (64, 128, 256, 512, 1024, 2048, 4096)


def _kepler(y: np.ndarray) -> np.ndarray:
    r3 = (y[0] ** 2 + y[1] ** 2) ** 1.5
    return np.array([y[2], y[3], -y[0] / r3, -y[1] / r3])


def kepler_error(tableau, n: int) -> float:
    """Error after one period with ``n`` equal steps of the float tableau."""
    e = ECCENTRICITY
    y0 = np.array([1 - e, 0.0, 0.0, np.sqrt((1 + e) / (1 - e))])
    A, b = tableau.A, tableau.b
    h = 2 * np.pi / n
    y = y0.copy()
    k = np.empty((tableau.stages, 4))
    for _ in range(n):
        for i in range(tableau.stages):
            k[i] = _kepler(y + h * (A[i, :i] @ k[:i]))
        y = y + h * (b @ k)
    return float(np.max(np.abs(y - y0)))


def main() -> None:
    names = [*PAIRS, *(q for q in QUENCHERS if q not in PAIRS), "vern87e"]
    print(
        "| name | role | order (embedded) | stages | f per step | FSAL "
        "| max abs a_ij | max abs b_i | float64 floor, Kepler |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for name in names:
        t = ALL_TABLEAUS[name]
        role = " + ".join(
            r for r, table in (("pair", PAIRS), ("quencher", QUENCHERS)) if name in table
        )
        order = f"{t.order} ({t.embedded_order})" if t.is_pair else f"{t.order}"
        floor = min(kepler_error(t, n) for n in STEPS)
        print(
            f"| `{name}` | {role or 'comparison'} | {order} | {t.stages} | "
            f"{t.evaluations_per_step} | {'yes' if t.fsal else 'no'} | {t.max_abs_a:.3g} | "
            f"{np.max(np.abs(t.b)):.3g} | {floor:.1e} |"
        )


if __name__ == "__main__":
    main()
