"""Make the figures of docs/ensembles.md from ensemble runs.

- ``ensemble_pendulum_phase_portrait.png``: pendulum orbits from q0 = 0 with
  p0 in [-3, 3] (and two just inside and outside the separatrix p0 = +-2),
  coloured by H; the separatrix p = +-2 cos(q/2) (H = 1) is dashed;
- ``ensemble_henon_heiles_section.png``: the Poincaré section q1 = 0
  (p1 > 0) at H = 1/8 from one ensemble: crossings located between kept
  samples by linear interpolation (sample spacing 0.02); the orbits that
  stopped early (their global error could no longer be guaranteed) in orange.

Run from the repository root: ``python docs/figures/ensemble_make_figures.py``;
it prints the numbers quoted in the docs.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

import hamrkq
from hamrkq.plotting import ensemble as plots
from hamrkq.plotting.figures import save_figure

HERE = Path(__file__).parent


def pendulum() -> None:
    p0 = np.concatenate([np.linspace(-3, 3, 31), [-2.02, -1.98, 1.98, 2.02]])
    p0 = np.sort(p0[p0 != 0])
    t_eval = np.linspace(0, 12, 1200)
    start = time.perf_counter()
    ens = hamrkq.ensemble(
        hamrkq.load_problem("pendulum"), q0=[0.0], p0=p0[:, None], t_span=(0, 12),
        t_eval=t_eval, progress=False,
    )  # fmt: skip
    wall = time.perf_counter() - start
    print(f"pendulum: {len(ens)} members, {ens.failed.size} failed, {wall:.2f} s, "
          f"largest energy drift {ens.energy_drift.max():.2e}, "
          f"largest estimated global error {ens.max_global_error.max():.2e}")  # fmt: skip
    fig = Figure(figsize=(7.5, 4.8), layout="constrained")
    ax = fig.add_subplot()
    plots.orbits(ens, wrap=2 * np.pi, ax=ax, linewidth=0.8)
    q = np.linspace(-np.pi, np.pi, 400)
    for sign in (1, -1):
        ax.plot(q, sign * 2 * np.cos(q / 2), "k--", lw=0.8)
    ax.set_title("Pendulum H = p²/2 - cos q: 34 orbits from one ensemble; separatrix dashed")
    save_figure(fig, HERE / "ensemble_pendulum_phase_portrait.png", dpi=110)


def henon_heiles() -> None:
    energy = 1 / 8
    q2, p2 = np.meshgrid(np.linspace(-0.4, 0.6, 9), np.linspace(-0.4, 0.4, 7), indexing="ij")
    q2, p2 = q2.ravel(), p2.ravel()
    # q1 = 0: H = (p1**2 + p2**2)/2 + q2**2/2 - q2**3/3; p1 > 0 from the energy.
    radicand = 2 * energy - p2**2 - q2**2 + 2 * q2**3 / 3
    keep = radicand > 0
    q0 = np.column_stack([np.zeros(keep.sum()), q2[keep]])
    p0 = np.column_stack([np.sqrt(radicand[keep]), p2[keep]])
    t_end = 300.0
    t_eval = np.arange(0, t_end + 1e-9, 0.02)
    start = time.perf_counter()
    ens = hamrkq.ensemble(
        hamrkq.load_problem("henon_heiles"), q0=q0, p0=p0, t_span=(0, t_end), t_eval=t_eval,
        atol=1e-9, progress=False,
    )  # fmt: skip
    wall = time.perf_counter() - start
    print(f"henon_heiles: {len(ens)} members, {ens.failed.size} failed, {wall:.2f} s, "
          f"H range {ens.energy0.min():.15f}..{ens.energy0.max():.15f}, "
          f"largest energy drift {ens.energy_drift.max():.2e}")  # fmt: skip
    q1, q2, p2 = ens.q[:, :, 0], ens.q[:, :, 1], ens.p[:, :, 1]
    up = (q1[:, :-1] < 0) & (q1[:, 1:] >= 0)  # q1 crosses 0 upward, so p1 > 0
    member, k = np.nonzero(up)
    s = -q1[member, k] / (q1[member, k + 1] - q1[member, k])
    x = q2[member, k] + s * (q2[member, k + 1] - q2[member, k])
    y = p2[member, k] + s * (p2[member, k + 1] - p2[member, k])
    print(f"henon_heiles: {member.size} crossings of q1 = 0")
    for status in sorted({ens.member_status(i) for i in ens.failed}, key=lambda s: s.code):
        stopped = [i for i in ens.failed if ens.member_status(i) is status]
        print(f"henon_heiles: {len(stopped)} members stopped with {status.name}, at t in "
              f"[{ens.t_last[stopped].min():.1f}, {ens.t_last[stopped].max():.1f}]")  # fmt: skip
    fig = Figure(figsize=(6.4, 5.6), layout="constrained")
    ax = fig.add_subplot()
    ok = ens.success[member]
    ax.scatter(x[ok], y[ok], s=0.6, c="tab:blue", linewidths=0, label="reached t = 300")
    ax.scatter(x[~ok], y[~ok], s=0.6, c="tab:orange", linewidths=0,
               label="stopped early: tolerance unattainable (chaotic)")  # fmt: skip
    ax.legend(loc="upper right", markerscale=8, fontsize="small")
    ax.set_xlabel("q2")
    ax.set_ylabel("p2")
    ax.set_title(f"Hénon-Heiles, H = 1/8: section q1 = 0 (p1 > 0), {len(ens)} orbits, t ≤ 300")
    save_figure(fig, HERE / "ensemble_henon_heiles_section.png", dpi=110)


if __name__ == "__main__":
    pendulum()
    henon_heiles()
