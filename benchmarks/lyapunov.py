"""The maximal Lyapunov exponent of a chaotic Henon-Heiles orbit against a
published value.

J. C. Sprott, *Chaos and Time-Series Analysis* (Oxford University Press,
2003), Appendix A.6.5 "Henon-Heiles system": for the orbit
(x, y, px, py) = (0.499, 0, 0, 0.03160676) at E = 1/8 the largest exponent
is 0.0450 (base e, per unit time).  The exponent is a property of the
chaotic sea, but one orbit's finite-time value converges slowly (the orbit
is sticky: it lingers near the islands), so this script reports both
Sprott's orbit to t = 10^6 and the mean over eight orbits of the same sea
(Sprott's, and x lowered in steps of 0.002 with py from H = 1/8) to
t = 5 10^4; ``tests/test_chaos.py`` checks the median of the first four
(robust to one sticky orbit, whose finite-time value is far below the sea's).

Run: ``python benchmarks/lyapunov.py`` (about a minute; 1.2 GB for the 10^6
run, whose every node the tangent sweep needs); writes ``lyapunov.txt``.
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import measure  # noqa: F401 - compiles a first use before timing (HAMRKQ_COMPILE=wait)
import numpy as np

import hamrkq

HERE = Path(__file__).resolve().parent
PUBLISHED = 0.0450
X0, PY0 = 0.499, 0.03160676


def sea_orbits(count: int) -> list[tuple[float, float]]:
    """(x, py) of ``count`` orbits of Sprott's energy, x lowered by 0.002."""
    energy = 0.5 * (X0**2 + PY0**2)
    return [(X0 - 0.002 * k, math.sqrt(2 * energy - (X0 - 0.002 * k) ** 2)) for k in range(count)]


def exponent(x: float, py: float, t_end: float) -> tuple[np.ndarray, np.ndarray]:
    hh = hamrkq.load_problem("henon_heiles")
    lam = hamrkq.lyapunov(hh, [x, 0.0], [0.0, py], (0.0, t_end), atol=1e-9, method="auto",
                          gamma_limit=math.inf, max_steps=10**8)  # fmt: skip
    assert lam.success, lam.message
    return lam.t, lam.value


def main() -> None:
    lines = [f"published (Sprott 2003, A.6.5): {PUBLISHED}"]
    started = time.perf_counter()
    t, value = exponent(X0, PY0, 1e6)
    for t_k in (1e5, 2.5e5, 5e5, 7.5e5, 1e6):
        k = int(np.searchsorted(t, t_k))
        k = min(k, t.size - 1)
        lines.append(f"Sprott's orbit, t = {t[k]:9.0f}: lambda = {value[k]:.4f} "
                     f"({value[k] / PUBLISHED - 1:+.1%})")  # fmt: skip
    lines.append(f"  ({time.perf_counter() - started:.1f} s)")
    finals = []
    for x, py in sea_orbits(8):
        finals.append(exponent(x, py, 5e4)[1][-1])
        lines.append(f"x = {x:.3f}, py = {py:.8f}, t = 5e4: lambda = {finals[-1]:.4f}")
    mean = float(np.mean(finals))
    lines.append(f"mean of the eight: {mean:.4f} ({mean / PUBLISHED - 1:+.1%}), "
                 f"spread {np.std(finals):.4f}")  # fmt: skip
    # a sticky orbit (trapped near the islands for most of 5e4) pulls a mean
    # far down; the median of the first four is what tests/test_chaos.py checks
    for count in (4, 8):
        median = float(np.median(finals[:count]))
        lines.append(f"median of the first {count}: {median:.4f} ({median / PUBLISHED - 1:+.1%})")
    text = "\n".join(lines) + "\n"
    print(text, end="")
    (HERE / "lyapunov.txt").write_text(text)


if __name__ == "__main__":
    main()
