"""Make the figures of docs/events.md (run from the repository root):

    python docs/figures/make_events_figures.py

- events_henon_heiles_section.png: Henon-Heiles at E = 1/8, 40 orbits on the
  line p2 = 0 of the section q1 = 0, t in [0, 2000], atol 1e-9 (the same as
  ``hamrkq poincare henon_heiles --energy 1/8 --orbits 40 --t-end 2000``);
- events_megno.png: MEGNO <Y>(t) for a regular (E = 1/8) and a chaotic
  (E = 1/6) Henon-Heiles orbit and the harmonic oscillator.
Prints the numbers quoted in the docs.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import sympy as sp
from matplotlib.figure import Figure

import hamrkq
from hamrkq.analysis.energy_surface import energy_orbits
from hamrkq.plotting.figures import save_figure
from hamrkq.plotting.sections import section_figure

HERE = Path(__file__).parent


def main() -> None:
    hh = hamrkq.load_problem("henon_heiles")
    q0, p0 = energy_orbits(hh.hamiltonian, 1 / 8, 40)
    sec = hamrkq.poincare(hh, "q1 = 0", q0, p0, (0.0, 2000.0), atol=1e-9, gamma_limit=math.inf)
    print(f"section: {sec.t.size} crossings")
    fig = section_figure(sec, "q2", "p2", title="Henon-Heiles, q1 = 0, E = 1/8, 40 orbits")
    save_figure(fig, HERE / "events_henon_heiles_section.png", dpi=110)

    fig = Figure(figsize=(6.5, 4.0), layout="constrained")
    ax = fig.add_subplot()
    q, p = sp.symbols("q p", real=True)
    osc = hamrkq.Hamiltonian(p**2 / 2 + 1.7**2 * q**2 / 2, q=[q], p=[p])
    runs = [
        ("harmonic oscillator", hamrkq.megno(osc, [1.0], [0.0], (0.0, 2000.0), atol=1e-10)),
    ]
    q8, p8 = energy_orbits(hh.hamiltonian, 1 / 8, 5)
    q6, p6 = energy_orbits(hh.hamiltonian, 1 / 6, 5)
    opts = dict(atol=1e-10, gamma_limit=math.inf)
    runs.append(
        (
            f"HH E=1/8, q2={q8[2, 1]:.3f} (regular)",
            hamrkq.megno(hh, q8[2], p8[2], (0, 2000), **opts),
        )
    )
    runs.append(
        (
            f"HH E=1/6, q2={q6[0, 1]:.3f} (chaotic)",
            hamrkq.megno(hh, q6[0], p6[0], (0, 2000), **opts),
        )
    )
    for label, y in runs:
        ax.plot(y.t, y.value, label=label)
        at = [np.searchsorted(y.t, s) for s in (500, 1000, 2000)]
        print(
            label,
            "<Y> at 500/1000/2000:",
            [round(float(y.value[min(i, y.t.size - 1)]), 3) for i in at],
        )
    ax.axhline(2.0, color="0.5", lw=0.8, ls="--")
    ax.set_yscale("symlog", linthresh=2.0)
    ax.set_xlabel("t")
    ax.set_ylabel("<Y>(t)")
    ax.set_title("MEGNO along three orbits")
    ax.legend()
    save_figure(fig, HERE / "events_megno.png", dpi=110)
    lam = hamrkq.lyapunov(hh, q6[0], p6[0], (0, 2000), **opts)
    print("lambda (chaotic, t=2000):", float(lam.value[-1]))


if __name__ == "__main__":
    main()
