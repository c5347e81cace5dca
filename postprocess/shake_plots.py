"""The PNG plots of one shaken run's analysis (matplotlib, Agg; written atomically): time
histories, spectra, the hysteresis loop and the kinetic energy, the steady window shaded green.
The quantities are those of postprocess.shake_signals, the maths postprocess.signal_analysis.
"""

from __future__ import annotations

from dem.output.atomic import savefig
from dem.output.plotting import agg_pyplot
from postprocess.shake_signals import KIND_OF, ShakeSignals
from postprocess.signal_analysis import SteadyWindow, spectral_peaks, spectrum


#: the unit of each kind of quantity (SI, as analysis.json)
UNIT_OF_KIND = {"displacement": "m", "velocity": "m/s", "acceleration": "m/s2"}


def shaken(sig: ShakeSignals, q: dict) -> tuple:
    """(t, q) cut to what the excitation covers, t <= t_end (s): after the last cycle the
    table's acceleration is 0 and it keeps its final velocity (dem.table_motion), a drift the
    structure follows, not a lag of it, which a plot must not show as one.  The table's own signals in
    ``sig.excitation`` are cut by the caller through the returned mask."""
    m = sig.t <= sig.t_end + 1e-9
    return sig.t[m], {k: v[m] for k, v in q.items()}, m


def plot_time_histories(path, sig: ShakeSignals, q: dict, win: SteadyWindow | None, title=""):
    """Absolute quantities (left, with the table's input) and relative ones (right), over the
    shaking only (:func:`shaken`)."""
    plt = agg_pyplot()
    fig, axs = plt.subplots(3, 2, figsize=(13, 8), sharex=True)
    t, q, m = shaken(sig, q)
    rows = [("displacement (mm)", 1e3, "displacement", ["da", "da_front"], ["ds", "dsr", "dar"]),
            ("velocity (mm/s)", 1e3, "velocity", ["va"], ["vs", "vsr", "var"]),
            ("acceleration (m/s2)", 1.0, "acceleration", ["a", "a_lp", "a_front"], ["ar"])]
    for (label, s, kind, absolute, relative), (ax_a, ax_r) in zip(rows, axs):
        ax_a.plot(t, s * sig.excitation[kind][m], color="0.6", lw=1.2, label="table (input)")
        for ax, names in ((ax_a, absolute), (ax_r, relative)):
            for nm in names:
                if nm in q:
                    ax.plot(t, s * q[nm], lw=0.8, label=nm)
            if win is not None:
                ax.axvspan(win.t0, win.t1, color="tab:green", alpha=0.08)
            if ax.lines:
                ax.legend(loc="upper right", fontsize=7, ncol=4)
            ax.grid(alpha=0.3)
        ax_a.set_ylabel(label)
        ax_r.set_ylabel(label)
    axs[0, 0].set_title(f"{title}: absolute")
    axs[0, 1].set_title("relative (to the table / to the corner)")
    for ax in axs[-1]:
        ax.set_xlabel(f"t (s)   (green: steady-state window; the shaking ends at "
                      f"{sig.t_end:.3g} s)")
    fig.tight_layout()
    savefig(fig, path, dpi=110)
    plt.close(fig)


def plot_spectrum(path, sig: ShakeSignals, q: dict, win: SteadyWindow, title=""):
    plt = agg_pyplot()
    names = [n for n in ("ds", "dsr", "da", "a") if n in q]
    fig, axs = plt.subplots(len(names), 1, figsize=(8, 2.2 * len(names)), squeeze=False)
    for ax, nm in zip(axs[:, 0], names):
        fr, amp = spectrum(sig.t, q[nm], win)
        ax.plot(fr, amp, lw=1.0)
        pk = spectral_peaks(fr, amp)
        for f0, a0 in pk["peaks"]:
            ax.plot([f0], [a0], "rv")
        ax.axvline(sig.f, color="0.5", ls="--", lw=0.8)
        ax.set_xlim(0, max(10.0, 4 * sig.f))
        ax.set_ylabel(f"|{nm}| ({UNIT_OF_KIND[KIND_OF[nm][0]]})")
        ax.grid(alpha=0.3)
    axs[-1, 0].set_xlabel(f"frequency (Hz)   (dashed: excitation; bins {1 / (win.t1 - win.t0):.3g}"
                          f" Hz apart over the {win.n_cycles}-cycle steady window)")
    axs[0, 0].set_title(title)
    fig.tight_layout()
    savefig(fig, path, dpi=110)
    plt.close(fig)


def plot_hysteresis(path, t, disp, force, win: SteadyWindow, title=""):
    plt = agg_pyplot()
    m = win.mask(t)
    fig, ax = plt.subplots(figsize=(6, 5))
    ax.plot(1e3 * disp[m], force[m], lw=0.7)
    ax.set_xlabel("ds (mm, relative to the table)")
    ax.set_ylabel("F = m_e a (N)")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    savefig(fig, path, dpi=110)
    plt.close(fig)


def plot_energy(path, t, e44, t_blocks, e_blocks, win, title=""):
    plt = agg_pyplot()
    fig, ax = plt.subplots(figsize=(9, 4))
    ax.plot(t, e44, lw=0.8, label="eq 4-4 from ds")
    if e_blocks is not None:
        ax.plot(t_blocks, e_blocks, lw=0.8, label="blocks: sum 1/2 m v^2 + 1/2 w.I.w")
    if win is not None:
        ax.axvspan(win.t0, win.t1, color="tab:green", alpha=0.08)
    ax.set_xlabel("t (s)")
    ax.set_ylabel("kinetic energy (J)")
    ax.set_title(title)
    ax.legend()
    ax.grid(alpha=0.3)
    fig.tight_layout()
    savefig(fig, path, dpi=110)
    plt.close(fig)
