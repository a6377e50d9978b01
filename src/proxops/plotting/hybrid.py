"""Figures of the ``hybrid`` system (Basu et al. Figs. 5-9), from a SimResult only.

- ``hybrid_fig5_contact.png``: the capture flow around the first contact(s): relative
  port velocity rho_dot and rate omega, jumping at each contact (Fig. 5).
- ``hybrid_fig6_displacement_controls.png``: |rho| and its components, |F_d| and |M_d|, with
  the post-capture mode shaded and contacts / mode changes marked (Fig. 6).
- ``hybrid_fig7_rotation.png``: relative attitude q and rate omega; the chief's p and
  omega_c (Fig. 7).
- ``hybrid_fig8_tracking.png``: post-capture orbit tracking error rho_n - r_des (Fig. 8).
- ``hybrid_fig9_decoupling.png``: the latch snap, decoupling and re-docking: |rho|, |rho_dot|,
  latch sensor and supervisor mode around the snap (Fig. 9).

The measured-state layout is :data:`proxops.propagation.hybrid_plant.HYBRID_LAYOUT`
(0:3 rho, 3:6 rho_dot, 6:9 omega, 9:13 q, 13:17 p, 17:20 omega_c, 20:23 rho_n, 23:26
rho_n_dot, 26:32 x_ref, 32 contacts, 33 latched). Indices are repeated here so that the
plots need nothing but the saved series.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from proxops.plotting.common import Drawing, draw_all, plt, save
from proxops.systems.hybrid import envelope_cells

POST = "post-capture"


def _events(result, kind: str) -> list[float]:
    return [float(t) for t, k, _ in result.events if k == kind]


def _post_intervals(result) -> list[tuple[float, float]]:
    """[(t_start, t_end)] of the samples in post-capture mode."""
    t = np.asarray(result.t)
    post = np.array([m == POST for m in result.mode])
    out, start = [], None
    for i, on in enumerate(post):
        if on and start is None:
            start = t[i]
        if not on and start is not None:
            out.append((start, t[i]))
            start = None
    if start is not None:
        out.append((start, t[-1]))
    return out


def _decorate(ax, result, legend: bool = False, window: tuple[float, float] | None = None) -> None:
    """Post-capture shaded, contacts (red dotted) and the snap (black dashed); only what falls in
    ``window`` (s) is drawn, so the legend lists no event the panel does not show."""
    lo, hi = window if window is not None else (-np.inf, np.inf)
    spans = [(max(a, lo), min(b, hi)) for a, b in _post_intervals(result) if b > lo and a < hi]
    for i, (a, b) in enumerate(spans):
        ax.axvspan(a, b, color="tab:green", alpha=0.10, label="post-capture (h = 1)" if i == 0 else None)
    for i, tc in enumerate(t for t in _events(result, "contact") if lo <= t <= hi):
        ax.axvline(tc, color="tab:red", ls=":", lw=0.8, label="contact" if i == 0 else None)
    snaps = [t for t, k, m in result.events if k == "snap" and not m.startswith("skipped") and lo <= t <= hi]
    for i, ts in enumerate(snaps):
        ax.axvline(ts, color="k", ls="--", lw=0.9, label="latch snap" if i == 0 else None)
    ax.grid(alpha=0.3)
    if legend:
        _legend(ax)


def _legend(ax, ncol: int = 1) -> None:
    """The legend beside the panel (right of the axes), never over the data."""
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7, ncol=ncol, borderaxespad=0.0)


def _attitude_deg(q: np.ndarray) -> np.ndarray:
    return np.degrees(2.0 * np.arctan2(np.linalg.norm(q[:, 0:3], axis=1), np.abs(q[:, 3])))


def plot_contact(result, path: Path, title: str = "") -> Path:
    """Fig. 5: rho_dot and omega components around the first contacts (jumps at the markers)."""
    t, x = result.t, result.x_true
    contacts = _events(result, "contact")
    t_end = min(t[-1], (contacts[0] + 30.0) if contacts else 60.0)
    sel = t <= t_end
    fig, axes = plt.subplots(3, 1, figsize=(8, 8), sharex=True)
    for i, c in enumerate("xyz"):
        axes[0].plot(t[sel], x[sel, 3 + i], label=rf"$\dot\rho_{c}$")
        axes[1].plot(t[sel], x[sel, 6 + i], label=rf"$\omega_{c}$")
        axes[2].plot(t[sel], x[sel, i], label=rf"$\rho_{c}$")
    axes[0].set_ylabel(r"$\dot\rho$ [m/s] (in C)")
    axes[1].set_ylabel(r"$\omega$ [rad/s] (in D)")
    axes[2].set_ylabel(r"$\rho$ [m] (in C)")
    axes[2].set_xlabel("time [s]")
    for ax in axes:
        _decorate(ax, result, window=(0.0, t_end))
        ax.set_xlim(0.0, t_end)
        _legend(ax)
    first = f"first contact at {contacts[0]:.2f} s" if contacts else "no contact"
    axes[0].set_title(f"{title}: capture flow with contact jumps ({first}; paper Fig. 5: 11 s)")
    return save(fig, path)


def plot_displacement_controls(result, path: Path, title: str = "") -> Path:
    """Fig. 6: |rho| (log) and components; |F_d|, |M_d| with mode bands."""
    t, x, u = result.t, result.x_true, result.u_applied
    fig, axes = plt.subplots(3, 1, figsize=(9, 8.5), sharex=True)
    for i, c in enumerate("xyz"):
        axes[0].plot(t, x[:, i], lw=1.0, label=rf"$\rho_{c}$")
    axes[0].set_ylabel(r"$\rho$ [m] (ports, in C)")
    axes[1].semilogy(t, np.maximum(np.linalg.norm(x[:, 0:3], axis=1), 1e-9), "k", lw=1.0, label=r"$|\rho|$")
    axes[1].set_ylabel(r"$|\rho|$ [m]")
    axes[2].plot(t, np.linalg.norm(u[:, 0:3], axis=1), lw=1.0, label=r"$|F_d|$ [N]")
    axes[2].plot(t, np.linalg.norm(u[:, 3:6], axis=1), lw=1.0, label=r"$|M_d|$ [N m]")
    axes[2].set_ylabel("control norms")
    axes[2].set_xlabel("time [s]")
    for i, ax in enumerate(axes):
        _decorate(ax, result)
        _legend(ax)
    axes[0].set_title(f"{title}: relative displacement between the ports and control norms (Fig. 6)")
    return save(fig, path)


def plot_rotation(result, path: Path, title: str = "") -> Path:
    """Fig. 7: q and omega (deputy relative to chief); p and omega_c (chief relative to T)."""
    t, x = result.t, result.x_true
    fig, axes = plt.subplots(2, 2, figsize=(12, 7), sharex=True)
    for i, c in enumerate("xyzw"):
        axes[0, 0].plot(t, x[:, 9 + i], lw=1.0, label=f"q_{c}")
        axes[0, 1].plot(t, x[:, 13 + i], lw=1.0, label=f"p_{c}")
    for i, c in enumerate("xyz"):
        axes[1, 0].plot(t, x[:, 6 + i], lw=1.0, label=rf"$\omega_{c}$")
        axes[1, 1].plot(t, x[:, 17 + i], lw=1.0, label=rf"$\omega_{{c,{c}}}$")
    axes[0, 0].set_ylabel("q (D rel. C)")
    axes[0, 1].set_ylabel("p (C rel. T)")
    axes[1, 0].set_ylabel(r"$\omega$ [rad/s]")
    axes[1, 1].set_ylabel(r"$\omega_c$ [rad/s]")
    for ax in axes.ravel():
        _decorate(ax, result)
        _legend(ax)
    for ax in axes[1]:
        ax.set_xlabel("time [s]")
    fig.suptitle(f"{title}: relative rotational states and the chief's attitude and rate (Fig. 7)")
    return save(fig, path)


def plot_tracking(result, path: Path, title: str = "") -> Path:
    """Fig. 8: rho_n - r_des components and norm (log) from the first dock on."""
    t, x = result.t, result.x_true
    err = x[:, 20:23] - x[:, 26:29]
    ivals = _post_intervals(result)
    t0 = ivals[0][0] if ivals else 0.0
    sel = t >= t0
    fig, axes = plt.subplots(2, 1, figsize=(9, 6.5), sharex=True)
    for i, c in enumerate("xyz"):
        axes[0].plot(t[sel], err[sel, i], lw=1.0, label=f"{c}")
    axes[0].set_ylabel(r"$\rho_n - r_{des}$ [m] (in T)")
    norm = np.linalg.norm(err[sel], axis=1)
    axes[1].semilogy(t[sel], np.maximum(norm, 1e-9), "k", lw=1.0, label=r"$|\rho_n - r_{des}|$")
    axes[1].axhline(1e-3, color="tab:blue", ls="--", lw=0.8, label="1 mm")
    axes[1].set_ylabel("tracking error [m]")
    axes[1].set_xlabel("time [s]")
    for ax in axes:
        _decorate(ax, result)
        _legend(ax)
        ax.set_xlim(t0, t[-1])
    axes[0].set_title(f"{title}: post-capture orbit tracking of the pair's CoM (Fig. 8)"
                      + ("" if ivals else " - never docked"))
    return save(fig, path)


def plot_decoupling(result, path: Path, title: str = "") -> Path:
    """Fig. 9: around the snap: |rho|, |rho_dot|, the latch sensor and the supervisor mode."""
    t, x = result.t, result.x_true
    snaps = [tt for tt, k, m in result.events if k == "snap" and not m.startswith("skipped")]
    if snaps:
        a, b = max(0.0, snaps[0] - 30.0), t[-1]
    else:
        a, b = 0.0, t[-1]
    sel = (t >= a) & (t <= b)
    h = np.array([1.0 if m == POST else 0.0 for m in result.mode])
    fig, axes = plt.subplots(3, 1, figsize=(9, 7.5), sharex=True)
    axes[0].semilogy(t[sel], np.maximum(np.linalg.norm(x[sel, 0:3], axis=1), 1e-9), lw=1.0, label=r"$|\rho|$ [m]")
    axes[0].semilogy(t[sel], np.maximum(np.linalg.norm(x[sel, 3:6], axis=1), 1e-9), lw=1.0,
                     label=r"$|\dot\rho|$ [m/s]")
    axes[0].set_ylabel("port separation")
    axes[1].plot(t[sel], x[sel, 33], drawstyle="steps-post", lw=1.2, label="latch locked")
    axes[1].plot(t[sel], h[sel] * 0.9, drawstyle="steps-post", lw=1.2, label="mode h (x0.9)")
    axes[1].set_ylabel("latch / mode")
    axes[1].set_ylim(-0.1, 1.2)
    axes[2].semilogy(t[sel], np.maximum(np.linalg.norm(x[sel, 20:23] - x[sel, 26:29], axis=1), 1e-9), "k", lw=1.0,
                     label=r"$|\rho_n - r_{des}|$ [m]")
    axes[2].set_ylabel("tracking error [m]")
    axes[2].set_xlabel("time [s]")
    for ax in axes:
        _decorate(ax, result)
        _legend(ax)
        ax.set_xlim(a, b)
    axes[0].set_title(f"{title}: latch snap, decoupling and re-docking (Fig. 9)"
                      + ("" if snaps else " - no snap in this run"))
    return save(fig, path)


def run_figures(sc, results: dict, out_dir: Path) -> list[Path]:
    """Figs. 5-9 of the main result of a run (drawn at once: :func:`proxops.plotting.common.draw_all`)."""
    out_dir = Path(out_dir)
    result = next(iter(results.values()))
    name = getattr(sc, "name", "hybrid")
    return draw_all([
        Drawing(plot_contact, out_dir / "hybrid_fig5_contact.png", result, title=name),
        Drawing(plot_displacement_controls, out_dir / "hybrid_fig6_displacement_controls.png", result, title=name),
        Drawing(plot_rotation, out_dir / "hybrid_fig7_rotation.png", result, title=name),
        Drawing(plot_tracking, out_dir / "hybrid_fig8_tracking.png", result, title=name),
        Drawing(plot_decoupling, out_dir / "hybrid_fig9_decoupling.png", result, title=name),
    ])


def mc_figures(sc, results: list, out_dir: Path) -> list[Path]:
    """Campaign overlay: |rho| and the tracking error of every saved run, mode bands omitted."""
    if not results:
        return []
    fig, axes = plt.subplots(2, 1, figsize=(9, 6.5), sharex=True)
    for r in results:
        x = r.x_true
        axes[0].semilogy(r.t, np.maximum(np.linalg.norm(x[:, 0:3], axis=1), 1e-9), lw=0.7, alpha=0.6)
        axes[1].semilogy(r.t, np.maximum(np.linalg.norm(x[:, 20:23] - x[:, 26:29], axis=1), 1e-9), lw=0.7, alpha=0.6)
    axes[0].set_ylabel(r"$|\rho|$ [m]")
    axes[1].set_ylabel(r"$|\rho_n - r_{des}|$ [m]")
    axes[1].set_xlabel("time [s]")
    for ax in axes:
        ax.grid(alpha=0.3)
    axes[0].set_title(f"{getattr(sc, 'name', 'hybrid')}: {len(results)} runs")
    return [save(fig, Path(out_dir) / "hybrid_mc_overlay.png")]


def plot_model_agreement(ts, errors: dict, blocks, path: Path) -> Path:
    """The relative model f_0 (eq. 32) against the direct two-body truth: max |error| per block
    over time, with our corrections (left) and with eq. 21's printed G2 (right)."""
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.8), sharey=True)
    for ax, corrected, title in ((axes[0], True, "corrected (standard CW G2)"), (axes[1], False, "printed eq. 21 G2")):
        for name, sl in blocks:
            ax.semilogy(ts, np.maximum(errors[corrected][:, sl].max(axis=1), 1e-17), label=name)
        ax.set_title(f"f_0 vs two-body truth: {title}", fontsize=9)
        ax.set_xlabel("t [s]")
        ax.grid(True, which="major", alpha=0.3)
    axes[0].set_ylabel("max |error| per block (SI units)")
    axes[1].legend(fontsize=7, loc="lower right")
    return save(fig, path)


def mc_table_figures(sc, table, out_dir: Path) -> list[Path]:
    """``hybrid_envelope.png`` of the capture-envelope grid (hybrid-envelope): one panel per
    capture thrust bound, port offset x tumble, success (o) / failure (x, reason initial), and
    the curve m_d omega^2 r = F above which no controller can stay on the turning docking axis."""

    cells = envelope_cells(sc, table)
    if not cells:
        return []
    forces = sorted({c[2] for c in cells})
    gap = 0.5 * (sc.chief.dims_m[1] + sc.deputy.dims_m[1])
    fig, axes = plt.subplots(1, len(forces), figsize=(4.2 * len(forces), 3.8), sharey=True, squeeze=False)
    for ax, f in zip(axes[0], forces):
        sub = [c for c in cells if c[2] == f]
        d_max = max(c[0] for c in cells)
        dd = np.linspace(0.3, d_max * 1.1, 200)
        w_lim = np.degrees(np.sqrt(f / (sc.deputy.mass_kg * (dd + gap))))
        ax.fill_between(dd, w_lim, 100.0, color="0.9", label="start point not holdable (m_d w^2 r > F)")
        r_dock = float(np.linalg.norm(np.array([0.0, gap, 0.0])))
        w_dock = math.degrees(math.sqrt(f / (sc.deputy.mass_kg * r_dock)))
        ax.axhspan(w_dock, 100.0, color="0.7", alpha=0.6, label="cannot dock (m_d w^2 r_dock > F)")
        for d, w, _, st, _, _ in sub:
            good = not st.startswith("fail")
            ax.plot(d, w, "o" if good else "x", color="tab:green" if good else "tab:red", ms=10, mew=2)
            if not good:
                ax.annotate(st.removeprefix("failed: ")[:18], (d, w), fontsize=6, xytext=(3, 3),
                            textcoords="offset points")
        ax.set_xscale("log")
        ax.set_ylim(-0.3, max(c[1] for c in cells) * 1.2 + 0.1)
        ax.set_title(f"capture thrust bound {f:g} N")
        ax.set_xlabel("port offset along the docking axis (m)")
    axes[0][0].set_ylabel("chief tumble (deg/s)")
    axes[0][0].legend(loc="upper left", fontsize=7)
    path = Path(out_dir) / "hybrid_envelope.png"
    return [save(fig, path)]
