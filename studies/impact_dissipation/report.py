"""summary.json, the plot and the README tables of the study.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from dem.output.plotting import agg_pyplot
from studies.impact_dissipation.physics import amplitude_after_impact
from studies.impact_dissipation.two_body import two_body_params


# ------------------------------------------------------------------------------------------
# the study
# ------------------------------------------------------------------------------------------
def rounded_record(d):
    """A record for summary.json: keys starting with _ dropped, numbers to 6 significant digits."""
    if isinstance(d, dict):
        return {k: rounded_record(v) for k, v in d.items() if not k.startswith("_")}
    if isinstance(d, list):
        return [rounded_record(v) for v in d]
    if isinstance(d, (np.floating, np.integer)):
        d = d.item()
    if isinstance(d, float) and math.isfinite(d) and d != 0.0:
        return float(f"{d:.6g}")
    return d


def compact_json(obj, indent: int = 0) -> str:
    """JSON with every list of scalars and every dict of scalars on one line (the summary stays
    readable and small)."""
    flat = lambda o: all(not isinstance(v, (dict, list)) for v in  # noqa: E731
                         (o.values() if isinstance(o, dict) else o))
    pad, pad1 = " " * indent, " " * (indent + 1)
    if isinstance(obj, (dict, list)) and (flat(obj) or not obj):
        return json.dumps(obj)
    if isinstance(obj, dict):
        items = [f"{pad1}{json.dumps(k)}: {compact_json(v, indent + 1)}" for k, v in obj.items()]
        return "{\n" + ",\n".join(items) + "\n" + pad + "}"
    if isinstance(obj, list):
        items = [pad1 + compact_json(v, indent + 1) for v in obj]
        return "[\n" + ",\n".join(items) + "\n" + pad + "]"
    return json.dumps(obj)


def housner_sequence(theta0: float, r: float, c: float, z: float, n: int) -> np.ndarray:
    """Amplitudes (rad) of n half cycles of a rigid block with restitution r released from
    theta0 (symmetric pivots, G at (c, z) from each)."""
    out = [theta0]
    for _ in range(n - 1):
        out.append(amplitude_after_impact(out[-1], r, c, z))
    return np.array(out)


def plot_histories(hist: dict, summary: dict, path: Path) -> None:
    """Figure 1: DEM rotation histories against Housner's peaks (a, b) and the damping
    dependence of the per-impact amplitude ratio (d)."""
    plt = agg_pyplot()

    fig, ax = plt.subplots(2, 2, figsize=(13, 8.5))
    a = ax[0, 0]
    for key, lab in (("a:excited-portion-block", "block b/h = 50/280"),
                     ("a:two-block-stack", "two-block stack (0.02 rad)")):
        if key in hist:
            h = hist[key]
            a.plot(h["_t"], np.degrees(h["_theta"]), lw=1, label=f"DEM {lab}")
            pk = np.abs(np.asarray(h["peaks_rad"]))
            if key == "a:excited-portion-block":
                hs = housner_sequence(h["theta0_rad"], h["housner_r"], h["b_m"] / 2, h["h_m"] / 2,
                                      len(pk))
            else:
                P = two_body_params("table-5.1")
                from dem.rocking.analysis import centre_of_mass_height
                hs = housner_sequence(h["theta0_rad"], h["housner_r"], 0.025,
                                      centre_of_mass_height(P), len(pk))
            a.plot(h["t_peaks_s"], np.degrees(hs) * np.sign(h["peaks_rad"]), "kx", ms=5)
    a.plot([], [], "kx", label="Housner's amplitudes (same release)")
    a.set(xlabel="t (s)", ylabel="rotation (deg)", title="(a) single bodies, default material")
    a.legend(fontsize=8)
    a.grid(alpha=0.3)
    b = ax[0, 1]
    for key, lab in (("b:upper-tilt", "upper part, side walls"),
                     ("b:upper-tilt-no-side-walls", "upper part, no side walls"),
                     ("b:portion-kick", "whole portion, kicked")):
        if key in hist:
            b.plot(hist[key]["_t"], np.degrees(hist[key]["_theta"]), lw=1, label=lab)
    if "b:upper-tilt-no-side-walls" in hist:
        h = hist["b:upper-tilt-no-side-walls"]
        c, z = h["pivot_outer_cz_m"]
        hs = housner_sequence(h["theta0_rad"], h["housner_r_outer_to_inner"], c, z, 8)
        tp = np.asarray(h["t_peaks_s"])[:8]
        b.plot(tp, np.degrees(hs[:len(tp)]) * np.sign(h["peaks_rad"][:len(tp)]), "kx",
               label="Housner, no side walls")
    b.set(xlabel="t (s)", ylabel="mean rotation about x (deg, + outwards)",
          title="(b) Model II y excited portion (DEM, rest of the box fixed, no roof)")
    b.legend(fontsize=8)
    b.grid(alpha=0.3)
    d = ax[1, 0]
    dd = summary.get("d_damping")
    if dd:
        zs = dd["zetas"]
        d.plot(zs, [1 - dd["block"][str(z)]["mean_amplitude_ratio"] for z in zs], "o-",
               label="block b/h = 50/280, released at alpha/2")
        d.plot(zs, [1 - dd["stack"][str(z)]["mean_amplitude_ratio"] for z in zs], "s-",
               label="two-block stack, 0.02 rad")
        blk = dd["block"]["0.5"]
        d.axhline(1 - blk["housner_first_amplitude_ratio"], color="C0", ls=":",
                  label="Housner, block at alpha/2")
        d.axhline(1 - dd["stack"]["0.5"]["housner_first_amplitude_ratio"], color="C1", ls=":",
                  label="Housner, stack at 0.02 rad")
        d.axvline(0.5, color="k", lw=0.8, ls="--")
    d.set(xlabel="contact damping ratio zeta", ylabel="amplitude lost per impact",
          title="(d) dependence on the damping ratio (default 0.5)")
    d.legend(fontsize=8)
    d.grid(alpha=0.3)
    e = ax[1, 1]
    c_ = summary.get("c_two_body")
    if c_:
        for k, (sc, ls) in enumerate((("co-moving-1.98", "-"), ("no-load-1.84", "--"))):
            for j, law in enumerate(c_["laws"]):
                rows = c_["runs"][f"{sc}|{law}"]
                f = [r["f_hz"] for r in rows if r["amplification"] is not None]
                A = [r["amplification"] for r in rows if r["amplification"] is not None]
                fc = [r["f_hz"] for r in rows if r["status"] == "collapsed"]
                lab = f"{sc}, {law} ({c_['laws'][law]})"
                e.plot(f, A, ls=ls, marker="o", color=f"C{j}", ms=3, label=lab)
                e.plot(fc, [0.1 * (k + 1)] * len(fc), "x", color=f"C{j}")
    e.set(xlabel="f (Hz)", ylabel="amplification of d (x: overturned)",
          title="(c) two-body model, Model II y, 20 cycles")
    e.legend(fontsize=7)
    e.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def markdown_tables(summary: dict) -> str:
    """The README's tables from summary.json (printed by ``--tables``)."""
    f3 = lambda x: "-" if x is None else f"{x:.3f}"  # noqa: E731
    lst = lambda xs, n=6: ", ".join(f"{x:.3f}" for x in xs[:n]) or "-"  # noqa: E731
    out = []
    a = summary.get("a_blocks", {})
    if a:
        out += ["| body | b/h | release (rad) | Housner r | Housner A1/A0 | DEM A_{k+1}/A_k | DEM r_eq "
                "(mean) | DEM omega+/omega- (mean) | CPU (s) |", "|---|---|---|---|---|---|---|---|---|"]
        for k, v in a.items():
            bh = v.get("b_over_h", 0.05 / 0.28)
            out.append(f"| {k} | {bh:.3f} | {v['theta0_rad']:.4f} | {f3(v['housner_r'])} | "
                       f"{f3(v['housner_first_amplitude_ratio'])} | {lst(v['amplitude_ratio'])} | "
                       f"{f3(v['mean_r_eq'])} | {f3(v.get('mean_omega_ratio'))} | {v['cpu_s']:.1f} |")
        out.append("")
    b = summary.get("b_portion", {})
    if b:
        out += ["| DEM run | bricks, mass (kg) | c_out, z (mm) | release | Housner r, facade edges "
                "(out-in, in-out; mean) | Housner r, far edge of the seat (width mm) | "
                "DEM peaks (rad) | DEM A_{k+1}/A_k | DEM r (same side, mean) | max rotation "
                "upper / lower (rad) | CPU (s) |",
                "|---|---|---|---|---|---|---|---|---|---|---|"]
        for k, v in b.items():
            if k == "two_body_free":
                continue
            rel = (f"tilt {v['theta0_rad']:.3f} rad" if v["start"] == "tilt"
                   else f"kick {v['omega0_rad_s']:.3f} rad/s (to {v['theta0_rad']:.3f} rad)")
            c, z = v["pivot_outer_cz_m"]
            lo = v["max_rotation_lower_rad"]
            out.append(f"| {k} | {v['n_bricks']}, {v['mass_kg']:.2f} | {1e3 * c:.1f}, {1e3 * z:.1f} | "
                       f"{rel} | {f3(v['housner_r_outer_to_inner'])}, "
                       f"{f3(v['housner_r_inner_to_outer'])}; {f3(v['housner_r_facade_edges_mean'])} | "
                       f"{f3(v['housner_r_far_edge'])} ({1e3 * v['seat_width_far_m']:.0f}) | "
                       f"{lst(v['peaks_rad'])} | "
                       f"{lst(v['amplitude_ratio'])} | {f3(v['mean_r_eq_same_side'])} | "
                       f"{v['max_rotation_upper_rad']:.3f} / {'-' if lo is None else f'{lo:.4f}'} | "
                       f"{v['cpu_s']:.1f} |")
        out.append("")
        tb = b.get("two_body_free", {})
        if tb:
            out += ["| two-body model (dem.rocking, plastic impacts) | start | locked-pair r | "
                    "peaks (rad) | A_{k+1}/A_k | r_eq |", "|---|---|---|---|---|---|"]
            for k, v in tb.items():
                out.append(f"| {k.replace('|', ', ')} | {v['initial']} | {f3(v['housner_restitution_locked'])} | "
                           f"{lst(v['peaks_rad'])} | {lst(v['amplitude_ratio'])} | {lst(v['r_eq'])} |")
            out.append("")
    c = summary.get("c_two_body", {})
    if c:
        laws = c["laws"]
        out += ["| scenario (peak m/s2) | " + " | ".join(f"{k} (e = {v})" for k, v in laws.items()) + " |",
                "|---|" + "---|" * len(laws)]
        scen = sorted({k.split("|")[0] for k in c["runs"]}, key=lambda s: list(c["runs"]).index(s + "|housner"))
        for sc in scen:
            if all(r["max_abs_d_m"] == 0.0 for law in laws for r in c["runs"][f"{sc}|{law}"]):
                fs = c["frequencies_hz"]
                out.append(f"| {sc} {fs[0]:.1f}-{fs[-1]:.1f} Hz | " + " | ".join(["rest"] * len(laws))
                           + " |")
                continue
            for i, f in enumerate(c["frequencies_hz"]):
                cells = []
                for law in laws:
                    r = c["runs"][f"{sc}|{law}"][i]
                    if r["status"] == "collapsed":
                        cells.append(f"overturns {r['t_end_s']:.2f} s")
                    elif r["max_abs_d_m"] == 0.0:
                        cells.append("rest")
                    else:
                        cells.append(f"A = {r['amplification']:.2f} ({1e3 * r['steady_P_m']:+.1f} / "
                                     f"{1e3 * r['steady_N_m']:+.1f} mm)")
                out.append(f"| {sc} {f:.1f} Hz | " + " | ".join(cells) + " |")
        out.append("")
    d = summary.get("d_damping", {})
    if d:
        out += ["| zeta | point restitution e_n | block b/h = 50/280: A_{k+1}/A_k (mean), r_eq | "
                "two-block stack: A_{k+1}/A_k (mean), r_eq | upper part, side walls: peaks | "
                "upper part, no side walls: A_{k+1}/A_k |", "|---|---|---|---|---|---|"]
        b50 = summary.get("b_portion", {})
        for z in d["zetas"]:
            k = str(z)
            bl, st = d["block"][k], d["stack"][k]
            up = d["upper"].get(k) or (b50.get("upper-tilt") if k == "0.5" else None)
            un = d["upper-no-side-walls"].get(k) or (
                b50.get("upper-tilt-no-side-walls") if k == "0.5" else None)
            out.append(f"| {z} | {d['point_restitution'][k]:.3f} | {bl['mean_amplitude_ratio']:.4f}, "
                       f"{bl['mean_r_eq']:.4f} | {st['mean_amplitude_ratio']:.4f}, {st['mean_r_eq']:.4f} | "
                       f"{lst(up['peaks_rad'], 4) if up else '-'} | "
                       f"{lst(un['amplitude_ratio'], 6) if un else '-'} |")
        blk, stk = d["block"]["0.5"], d["stack"]["0.5"]
        out.append(f"| Housner | - | {blk['housner_first_amplitude_ratio']:.4f}, {blk['housner_r']:.4f} | "
                   f"{stk['housner_first_amplitude_ratio']:.4f}, {stk['housner_r']:.4f} | - | - |")
        out.append("")
    cpu = summary.get("cpu_s", {})
    if cpu:
        out += ["| part | CPU (s) |", "|---|---|"] + [f"| {k} | {v:.1f} |" for k, v in cpu.items()]
    return "\n".join(out)


