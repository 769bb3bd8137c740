"""Cost of dense output and events against a plain run (compiled backend, warm).

    python benchmarks/events.py

Kepler e = 0.6 over 100 orbits at atol 1e-12 (auto): plain; dense_output=True;
the pericentre event ``q1*p1 + q2*p2`` (direction +1); Prentice's problem
at atol 1e-9 with the event ``q`` (its zero crossings); and an anharmonic
oscillator (``v**2/2 + 2 x**2 + x**4/100``) over t <= 10 000 at atol 1e-9
with two events, ``x`` upward and ``v - 1/2`` both ways (about 9 500
roots: where locating them, not integrating, is the cost).  Median of 3
runs each.  Prints and writes ``benchmarks/events.txt`` (with the number of
roots each event run found).
"""

from __future__ import annotations

import datetime
import math
import os
import statistics
import time
from pathlib import Path

import measure  # noqa: F401 - compiles a first use before timing (HAMRKQ_COMPILE=wait)
import sympy as sp

import hamrkq

HERE = Path(__file__).resolve().parent


def timed(fn, repeat: int = 3) -> tuple[float, int | None]:
    """Median wall time of ``repeat`` warm runs, and the roots the run found."""
    sol = fn()  # warm: compile or load
    times = []
    for _ in range(repeat):
        started = time.perf_counter()
        fn()
        times.append(time.perf_counter() - started)
    roots = sum(len(t) for t in sol.t_events) if sol.t_events else None
    return statistics.median(times), roots


def main() -> None:
    kepler = hamrkq.load_problem("kepler", e=0.6)
    span = (0.0, 200 * math.pi + 1.0)
    opts = dict(t_span=span, atol=1e-12, method="auto", gamma_limit=math.inf)
    peri = {"expression": "q1*p1 + q2*p2", "direction": 1}
    cases = {
        "kepler plain": lambda: hamrkq.solve(kepler, **opts),
        "kepler dense_output": lambda: hamrkq.solve(kepler, dense_output=True, **opts),
        "kepler pericentre event": lambda: hamrkq.solve(kepler, events=peri, **opts),
    }
    prentice = hamrkq.load_problem("prentice2011")
    cases["prentice2011 plain"] = lambda: hamrkq.solve(prentice, atol=1e-9)
    cases["prentice2011 event q"] = lambda: hamrkq.solve(prentice, atol=1e-9, events="q")
    x, v = sp.symbols("x v")
    oscillator = hamrkq.Hamiltonian(v**2 / 2 + 2 * x**2 + x**4 / 100, q=[x], p=[v])
    many = dict(q0=[0.5], p0=[0.0], t_span=(0.0, 1e4), atol=1e-9)
    roots = [{"expression": "x", "direction": 1}, "v - 1/2"]
    cases["oscillator plain"] = lambda: hamrkq.solve(oscillator, **many)
    cases["oscillator 2 events"] = lambda: hamrkq.solve(oscillator, events=roots, **many)
    now = datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC")
    load = os.getloadavg()[0]
    lines = [f"benchmarks/events.py, run {now}, load average {load:.2f} at the start"]
    results = {name: timed(fn) for name, fn in cases.items()}
    for name, (seconds, found_roots) in results.items():
        base = results[name.split()[0] + " plain"][0]
        found = "" if found_roots is None else f"   {found_roots} roots"
        lines.append(f"{name:28s} {seconds:8.3f} s   {seconds / base:5.2f}x plain{found}")
    lines.append(f"load average {os.getloadavg()[0]:.2f} at the end")
    text = "\n".join(lines) + "\n"
    print(text, end="")
    (HERE / "events.txt").write_text(text)


if __name__ == "__main__":
    main()
