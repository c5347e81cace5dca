"""``<out>/summary.json`` and ``<out>/README.md``: the per-sweep numbers, the criteria, the tables
shown beside them (acceleration, front / back, cycles checks) and the plots.
"""

from __future__ import annotations

import json
from pathlib import Path

from dem.output.plotting import agg_pyplot
from postprocess.shake_signals import LOWPASS_HZ, LOWPASS_ORDER, LOWPASS_SENSITIVITY_HZ
from postprocess.verdicts import band_text, finite, fmt
from studies.kit.records import read_json
from studies.prediction.analysis import analyse_sweep, survived
from studies.prediction.criteria import criteria, false_success_checks
from studies.prediction.cycles import verdict_text
from studies.prediction.points import points_path
from studies.prediction.protocol import CHAPTER3_CHECK, CYCLES_RULE, ORDER, THESIS


# ---- report -------------------------------------------------------------------------------------
def read_cycles_checks(out: Path) -> dict:
    """sweep -> [{cycles, full_cycles, verdict}] from the committed cycles-check-<N>.json files."""
    res = {}
    for n in ORDER:
        for path in sorted((Path(out) / n).glob("cycles-check-*.json")):
            d = read_json(path)
            if d and d.get("kind") == "prediction-cycles-check":
                res.setdefault(n, []).append({k: d.get(k) for k in (
                    "cycles", "full_cycles", "n_runs", "n_runs_sweep", "verdict")})
    return res


def thesis_io(sw: dict) -> dict:
    return (sw.get("inside_outside") or {}).get("thesis_range") or {}


def acceleration_table(summary: dict) -> list[str]:
    """README lines: a's amplification inside the thesis' range, raw and low-passed (the
    assumed instrument and the cutoff sensitivity), against the thesis' ~2 (Model II y)."""
    cut = [f"{c:g}" for c in sorted(LOWPASS_SENSITIVITY_HZ, reverse=True)]
    L = ["## Acceleration amplification (not a criterion: the instrument filter is assumed)", "",
         f"The DEM's accelerometer is ideal (500 Hz samples of the rigid brick, every impact "
         f"spike kept); the thesis names no sampling rate or filter for its accelerometers "
         f"(Section 4.2.5).  `a_lp` is `a` through an ASSUMED instrument: a Butterworth of "
         f"order {LOWPASS_ORDER} at {LOWPASS_HZ:g} Hz run forward and backward (zero phase; >= "
         f"5 harmonics of the highest test frequency 3.6 Hz).  Because the answer depends on "
         f"the cutoff, the median inside the thesis' range is also given at other cutoffs.", "",
         "| sweep | thesis a inside | a raw | a_lp (" + f"{LOWPASS_HZ:g}" + " Hz) | "
         + " | ".join(f"median at {c} Hz" for c in cut) + " | median raw |",
         "|---|---|---|---|" + "---|" * (len(cut) + 1)]
    for n in ORDER:
        sw = summary.get(n) or {}
        acc = thesis_io(sw).get("acceleration_inside")
        if not sw.get("n_run") or not acc:
            continue
        sens = acc.get("cutoff_sensitivity") or {}
        th = THESIS.get(n, {}).get("a_in")
        L.append(f"| {n} | {f'~{th:g}' if th else '-'} | {band_text(acc.get('a'))} | "
                 f"{band_text(acc.get('a_lp'))} | "
                 + " | ".join(fmt((sens.get(c) or {}).get("median")) for c in cut + ["raw"])
                 + " |")
    return L + [""]


def front_back_table(summary: dict) -> list[str]:
    """README lines: front and back facade amplification inside the thesis' range and their
    ratio, against the thesis' Tables 4.9 - 4.11 (context, not a criterion)."""
    L = ["## Front / back facade (context, not a criterion)", "",
         "The thesis (Section 4.3.4, Tables 4.9 - 4.11) found the back facade (L1 / T1, near the "
         "actuators, carrying the instruments) rocking more than the front one (L2 / T2), with a "
         "front / back ratio constant over frequency: 0.359 (Model II y), 0.618 (II x), 0.587 "
         "(III y).  The front facade carried one accelerometer only (A5, on its centre brick), "
         "so these are accelerometer amplifications; the thesis does not say whether of a or of "
         "its double integral da.  Shown here: da (the headline: free of impact spikes and of "
         "the assumed filter) and a_lp, the front facade's centre accelerometer against the "
         "back one's.  The DEM's box model is symmetric front to back up to the imperfections' "
         "random draws, and its table is rigid and moves the whole base at once: the only "
         "asymmetry it has is the excitation's sign (the sine starts towards one side), which "
         "averages out over the cycles.  It has no reason to reproduce the thesis' ratio, "
         "which the thesis itself puts down to the discrete models and to the side walls "
         "damping the input on its way to the front.", "",
         "| sweep | thesis ratio | front da | back da | ratio da (front / back) | "
         "ratio a_lp | median ratio da per frequency |", "|---|---|---|---|---|---|---|"]
    for n in ORDER:
        sw = summary.get(n) or {}
        fb = thesis_io(sw).get("front_back_inside")
        if not sw.get("n_run") or not fb:
            continue
        per_f = (sw.get("front_back_curves") or {}).get("da") or {}
        th = THESIS.get(n, {}).get("front_back")
        L.append(f"| {n} | {fmt(th)} | {band_text(fb['da']['front'])} | {band_text(fb['da']['back'])} | "
                 f"{band_text(fb['da']['ratio'])} | {band_text(fb['a_lp']['ratio'])} | "
                 + ", ".join(f"{f}: {fmt(st.get('median'))}" for f, st in per_f.items()
                             if st.get("n")) + " |")
    return L + [""]


def cycles_table(checks: dict) -> list[str]:
    """README lines: the cycles check of each sweep that has one (:func:`cycles_check`)."""
    L = ["## Fewer cycles: does the cut change the answer? (issue 13 step 3)", "",
         "The finished runs re-analysed over their first N cycles (no new simulation: a run's "
         "first cycles do not depend on how many follow; module docstring).  Rule: "
         + CYCLES_RULE + ".", ""]
    if not checks:
        return L + ["No cycles check yet (`--cycles-check N`).", ""]

    def med(v):
        return f"{fmt(v.get('short'))} / {fmt(v.get('full'))}"
    L += ["| sweep | N / full cycles | runs compared | f_c (Hz) | ds inside | ds outside | "
          "lowest survival | answer |", "|---|---|---|---|---|---|---|---|"]
    for n, lst in checks.items():
        for c in lst:
            v = c["verdict"]
            fc, sv = v["characteristic_frequency"], v["survival"]
            ans = verdict_text(v)
            n_all = c.get("n_runs_sweep", c.get("n_runs"))
            L.append(f"| {n} | {c['cycles']:g} / {c['full_cycles']:g} | "
                     f"{c.get('n_runs')} of {n_all} | "
                     f"{fc['short'] if fc['short'] is not None else 'none'} / "
                     f"{fc['full'] if fc['full'] is not None else 'none'} | "
                     f"{med(v['amplification_ds_inside'])} | "
                     f"{med(v['amplification_ds_outside'])} | "
                     f"{fmt(sv['short'], '.0%')} / {fmt(sv['full'], '.0%')} | {ans} |")
    return L + [""]


def report(out: Path, frozen: dict, command: str, runs: Path | None = None) -> dict:
    """summary.json and README.md of ``out`` from plan.json and the sweeps' points.json."""
    from dem.output.atomic import write_json

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    plan = read_json(out / "plan.json")
    summary = {n: analyse_sweep(n, read_json(points_path(out, n))) for n in ORDER}
    crit = criteria(summary, read_json(out / CHAPTER3_CHECK))
    checks = false_success_checks(plan, summary)
    cycles = read_cycles_checks(out)
    cpu = sum((s.get("cpu_seconds") or 0.0) for s in summary.values())
    data = {"kind": "prediction-summary", "command": command,
            "frozen": {k: frozen[k] for k in ("path", "parameters", "provenance", "sha256",
                                              "commit")},
            "freezing_commit": frozen["commit"], "plan": plan, "cpu_seconds": cpu,
            "low_pass": {"quantities": ["a_lp", "a_front_lp"], "cutoff_hz": LOWPASS_HZ,
                         "order": LOWPASS_ORDER, "zero_phase": True,
                         "sensitivity_cutoffs_hz": list(LOWPASS_SENSITIVITY_HZ),
                         "note": "an ASSUMED instrument (the thesis gives no sampling rate or "
                                 "filter); not a criterion; the unfiltered 'a' is kept"},
            "sweeps": summary, "criteria": crit, "false_success_checks": checks,
            "cycles_checks": cycles}
    write_json(out / "summary.json", data, indent=1)
    L = ["# Blind prediction of Chapter 4 (issue 13, steps 3-5)", "",
         f"Generated by `{command}`; `--report` rebuilds this page and summary.json from "
         "plan.json and the committed `<sweep>/points.json` files.", "",
         f"Frozen set: `{frozen['path']}`, frozen in commit `{frozen['commit']}` "
         f"(the last commit that changed it): `{json.dumps(frozen['parameters'])}`"
         + (f"; provenance {json.dumps(frozen['provenance'])}" if frozen["provenance"] else ""),
         "",
         f"Plan (written before the first run): seeds {plan['seeds'] if plan else '-'}, "
         f"{plan['cycles'] if plan else '-'} cycles after settling"
         + "".join(f"; {n} CUT to {c['cycles']:g} cycles ({c['justified_by']}: {c['verdict']})"
                   for n, c in ((n, s.get("cut")) for n, s in
                                ((plan or {}).get("sweeps") or {}).items()) if c)
         + (f", runs capped at {plan['max_steps']} steps (SMOKE, not a prediction)"
            if plan and plan.get("max_steps") else "") + f".  CPU time so far: {cpu:.0f} s.", "",
         "Amplification of ds (thesis Section 4.2.5), median (10 % - 90 %) over the realisations "
         "that survived; inside / outside: the per-realisation means over the sweep frequencies "
         "inside / outside the thesis' effective range.  The characteristic frequency is the peak "
         "of the median curve by postprocess.sweep.effective_range, null when the peak is at an "
         "edge of the sweep or not clear.  The acceleration and the front / back facades: "
         "their own tables below (not criteria).", "",
         "## Per sweep", "",
         "| sweep | done | thesis f_c (Hz) | DEM f_c (Hz) | per-seed f_c | DEM range (Hz) | "
         "ds inside (thesis range) | ds outside | lag inside (s) | excited bricks | courses | "
         "survival (lowest f) | CPU s |", "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for n in ORDER:
        s, th = summary[n], THESIS.get(n, {})
        if s.get("status") == "pending" and not s.get("n_run"):
            L.append(f"| {n} | 0 | {th.get('fc') or th.get('fc_note', '-')} | not run | | | | | "
                     f"| | | | |")
            continue
        io = (s.get("inside_outside") or {}).get("thesis_range") or {}
        fc = s.get("characteristic_frequency_hz")
        fc_txt = fmt(fc, "g") if fc is not None else \
            f"none: {s.get('characteristic_frequency_note')}"
        sv = (s.get("survival") or {}).get("min_rate")
        L.append(f"| {n} | {s['n_run']}/{s['n_expected']} | "
                 f"{th.get('fc') if th.get('fc') is not None else th.get('fc_note', '-')} | "
                 f"{fc_txt} | {band_text(s.get('characteristic_frequency_band'), 'g')} | "
                 f"{s.get('effective_range_hz') or '-'} | "
                 f"{band_text(io.get('amplification_ds_inside'))} | "
                 f"{band_text(io.get('amplification_ds_outside'))} | "
                 f"{band_text(io.get('lag_ds_inside_s'))} | {band_text(s.get('excited_bricks'), 'g')} | "
                 f"{band_text(s.get('excited_courses'), 'g')} | "
                 f"{f'{sv:.0%}' if sv is not None else '-'} | {fmt(s.get('cpu_seconds'), '.0f')} |")
    L += [""] + acceleration_table(summary) + front_back_table(summary) + cycles_table(cycles)
    L += ["## Success criteria (issue 13 step 4)", "",
          "Each criterion passes only when the median agrees within the tolerance AND the thesis "
          "value lies inside the 10-90 % band of the realisations.", "",
          "| sweep | quantity | thesis | status | detail |", "|---|---|---|---|---|"]
    for r in crit:
        L.append(f"| {r['sweep']} | {r['quantity']} | {r['thesis']} | **{r['status']}** | "
                 f"{r.get('why', '')} |")
    L += ["", "## False successes rejected (issue 13 step 5)", "",
          "| check | status | detail |", "|---|---|---|"]
    for r in checks:
        L.append(f"| {r['check']} | **{r['status']}** | {r['why']} |")
    L += ["", "## Figures", ""]
    for n in ORDER:
        s = summary[n]
        if not s.get("n_run"):
            continue
        if plot_sweep(out / n / "amplification.png", n, s):
            L.append(f"![{n}]({n}/amplification.png)")
        exc = copy_excited(out, n, s, runs)
        if exc:
            L.append(f"![{n} excited portion]({exc})")
        L.append("")
    (out / "README.md").write_text("\n".join(L) + "\n")
    return data


def plot_sweep(path: Path, name: str, sw: dict) -> bool:
    """Amplification of ds, da and dsr against frequency: median with the 10-90 % band over the
    surviving realisations; the thesis' characteristic frequency, effective range and
    amplifications (REFERENCE.md, Chapter 4) drawn over them."""
    curves = sw.get("amplification_curves") or {}
    ds = curves.get("ds") or {}
    fs = sorted(float(f) for f, st in ds.items() if st.get("n"))
    if not fs:
        return False
    plt = agg_pyplot()

    from dem.output.atomic import savefig

    th = THESIS.get(name, {})
    fig, ax = plt.subplots(figsize=(7, 4))
    for q, c in (("ds", "C0"), ("da", "C1"), ("dsr", "C2")):
        st = [(curves.get(q) or {}).get(f"{f:g}") or {} for f in fs]
        ok = [i for i, x in enumerate(st) if x.get("n")]
        if not ok:
            continue
        f_ok = [fs[i] for i in ok]
        ax.fill_between(f_ok, [st[i]["q10"] for i in ok], [st[i]["q90"] for i in ok], color=c,
                        alpha=0.2)
        ax.plot(f_ok, [st[i]["median"] for i in ok], "o-", color=c,
                label=f"{q}: median, 10-90 % band")
    if th.get("range"):
        ax.axvspan(th["range"][0], th["range"][1], color="0.5", alpha=0.15,
                   label="thesis effective range")
    if th.get("fc"):
        ax.axvline(th["fc"], color="k", ls="--", lw=1, label=f"thesis f_c {th['fc']:g} Hz")
    if th.get("amp_in") is not None and th.get("range"):
        ax.plot(th["range"], [th["amp_in"]] * 2, "k-", lw=3, label="thesis ds inside")
    if sw.get("characteristic_frequency_hz") is not None:
        ax.axvline(sw["characteristic_frequency_hz"], color="C3", lw=1,
                   label=f"DEM f_c {sw['characteristic_frequency_hz']:g} Hz")
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel("amplification")
    ax.set_title(f"{name}: {len(sw.get('seeds') or [])} realisations"
                 + (" (SMOKE: capped steps)" if sw.get("smoke") else ""))
    ax.legend(fontsize=7)
    fig.tight_layout()
    savefig(fig, path, dpi=100)
    plt.close(fig)
    return True


def copy_excited(out: Path, name: str, sw: dict, runs: Path | None = None) -> str | None:
    """Copy the excited-portion drawing (postprocess.excited_output, excited.png) of the
    realisation whose excited-brick count is nearest the median, at the frequency of
    ``excited_at_hz``, from the raw runs to ``<out>/<sweep>/``; its path relative to out.  The
    drawings of other realisations copied there before (the median moved) are removed."""
    import shutil

    f, med = sw.get("excited_at_hz"), (sw.get("excited_bricks") or {}).get("median")
    data = read_json(points_path(out, name)) or {}
    rows = [r for r in data.get("rows") or [] if f is not None
            and abs(r["frequency_hz"] - f) < 1e-9 and survived(r)
            and finite((r.get("excited") or {}).get("n_excited"))]
    if not rows or med is None:
        return None
    r = min(rows, key=lambda r: (abs(r["excited"]["n_excited"] - med), r["seed"]))
    from dem.run.sweep import point_name

    src = (runs or Path(out) / "runs") / name / f"seed-{r['seed']}" / point_name(f) / "excited.png"
    if not src.is_file():
        return None
    dst = Path(out) / name / f"excited-{f:g}Hz-seed{r['seed']}.png"
    shutil.copyfile(src, dst)
    for old in dst.parent.glob("excited-*Hz-seed*.png"):
        if old != dst:
            old.unlink()
    return str(dst.relative_to(out))


