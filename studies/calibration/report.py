"""``<out>/summary.json`` and ``<out>/README.md``: the points, the scores, the selection
(studies.calibration.select), the held-out walls and the cost estimate.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from dem.engine import RESULTS_REVISION
from studies.calibration.points import point_path
from studies.calibration.scoring import point_summary, score_candidate, summary_finished
from studies.calibration.select import is_perfect, select, selection_lines
from studies.calibration.specimens import (fingerprint, HELD_OUT_DIR, held_out_specimens,
                                           realisations_for, specimen_case, TARGETS)
from studies.kit.provenance import rel
from studies.kit.records import read_json


# ---- report -------------------------------------------------------------------------------------
def collect(out: Path, candidates: dict, specs: dict, n: int | None = None) -> dict:
    """candidate -> specimen -> point_summary, from the committed point files.  With ``n``
    (the study's N), a point whose fingerprint is not this code's for that case (an earlier
    RESULTS_REVISION, another case; smoke points capped by --max-steps excepted) is reported
    as pending, ``stale``: its numbers are not this engine's."""
    res: dict = {}
    for c, params in candidates.items():
        res[c] = {}
        for s in specs:
            data = read_json(point_path(out, c, s))
            p = point_summary(data)
            cal = (data or {}).get("calibration") or {}
            if n is not None and cal and cal.get("max_steps") is None:
                case = specimen_case(specs[s]["path"], params, f"cal-{c}-{s}")
                if cal.get("fingerprint") != fingerprint(case, realisations_for(params, n), None):
                    p = {"status": "pending", "stale": True, "n_ok": 0,
                         "n_realisations": cal.get("n_realisations")}
            res[c][s] = {"l_over_h": specs[s]["l_over_h"], "kind": specs[s]["kind"],
                         **{k: v for k, v in p.items()
                            if v is not None or k not in ("l_over_h", "kind")}}
    return res


def held_out_summary(out: Path) -> dict:
    """specimen -> the held-out point's point_summary with the thesis' lambda, the frozen set it
    ran with (file, commit), the median's relative difference from the thesis and whether the
    thesis value lies in the 10-90 % band (pending points: no numbers)."""
    res = {}
    for s, spec in held_out_specimens().items():
        data = read_json(point_path(out, HELD_OUT_DIR, s))
        p = {**point_summary(data), "l_over_h": spec["l_over_h"],
             "thesis_lambda": spec["thesis_lambda"],
             "frozen": ((data or {}).get("calibration") or {}).get("frozen")}
        if summary_finished(p) and p.get("lambda_median") is not None:
            lam = spec["thesis_lambda"]
            p["relative_difference"] = p["lambda_median"] / lam - 1.0
            p["thesis_in_band"] = bool(p["lambda_q10"] <= lam <= p["lambda_q90"])
        res[s] = p
    return res


def held_out_lines(held: dict) -> list[str]:
    """The report's section on the held-out large-brick walls."""
    L = ["## Held out: the large-brick walls (L/H = 2.5)", ""]
    if not any(p.get("n_ok") for p in held.values()):
        return L + ["Their test lambdas (0.48 stretcher flat, 0.45 English, 0.36 stretcher on "
                    "edge; Section 3.3.3) are the only ones the text gives; they are not used "
                    "to choose the set.  After the freeze they are predicted with the frozen set "
                    "unchanged: `python -m studies calibration --out "
                    "results/calibration --held-out` (not run yet).", ""]
    frozen = {json.dumps(p["frozen"], sort_keys=True) for p in held.values() if p.get("frozen")}
    L += ["Predicted with the frozen set unchanged (its lengths in metres, not scaled to the "
          "larger brick): " + "; ".join(f"`{f}`" for f in sorted(frozen)) + ".", "",
          "| specimen | L/H | thesis lambda | done | median lambda | 10-90 % | thesis in band | "
          "median vs thesis | mechanisms |", "|---|---|---|---|---|---|---|---|---|"]
    for s, p in held.items():
        done = f"{p.get('n_ok', 0)}/{p.get('n_realisations') or '-'}"
        if summary_finished(p) and p.get("lambda_median") is not None:
            mech = ", ".join(f"{k} {v}" for k, v in (p.get("mechanisms") or {}).items()) or "-"
            L.append(f"| {s} | {fmt_fixed(p['l_over_h'], 2)} | {p['thesis_lambda']} | {done} | "
                     f"{fmt_fixed(p['lambda_median'], 4)} | {fmt_fixed(p['lambda_q10'], 4)} - "
                     f"{fmt_fixed(p['lambda_q90'], 4)} | {'yes' if p['thesis_in_band'] else 'no'} | "
                     f"{100 * p['relative_difference']:+.0f} % | {mech} |")
        else:
            L.append(f"| {s} | {fmt_fixed(p['l_over_h'], 2)} | {p['thesis_lambda']} | {done} | "
                     "pending | pending | - | - | pending |")
    return L + [""]


def estimate(points: dict, specs: dict, candidates: dict, n: int) -> dict:
    """CPU seconds per realisation of each specimen and the whole grid's estimate (n
    realisations per imperfect point, one per perfect one).

    Measured: the mean over a specimen's finished imperfect points (their own CPU, settling and
    process start included).  Where a specimen has none yet: its perfect point's CPU times the
    median ratio imperfect / perfect over the specimens that have both (imperfect runs settle
    first and step the warped-face kernels).  None while no perfect point is finished."""
    def per_real(ps):
        vals = [p["cpu_seconds"] / max(p["n_realisations"], 1) for p in ps
                if p.get("cpu_seconds")]
        return float(np.mean(vals)) if vals else None

    perfect = [c for c in candidates if is_perfect(candidates[c])]
    imperfect = [c for c in candidates if not is_perfect(candidates[c])]
    meas = {s: per_real([points[c][s] for c in imperfect if summary_finished(points[c][s])])
            for s in specs}
    base = {s: per_real([points[c][s] for c in perfect if summary_finished(points[c][s])])
            for s in specs}
    ratios = [meas[s] / base[s] for s in specs if meas[s] and base[s]]
    ratio = float(np.median(ratios)) if ratios else None
    per, how = {}, {}
    for s in specs:
        if meas[s] is not None:
            per[s], how[s] = meas[s], "measured"
        elif base[s] is not None and ratio is not None:
            per[s], how[s] = base[s] * ratio, f"perfect x {ratio:.2f}"
        else:
            per[s], how[s] = None, "unknown"
    known = all(v is not None for v in per.values())
    total = sum(v * n * len(imperfect) + (base[s] or v) * len(perfect)
                for s, v in per.items()) if known else None
    done = sum(p.get("cpu_seconds") or 0.0 for c in points for p in points[c].values()
               if summary_finished(p))
    return {"cpu_seconds_per_realisation": per, "how": how, "imperfect_over_perfect": ratio,
            "grid_cpu_seconds": total, "finished_cpu_seconds": done,
            "basis": "per specimen: its finished imperfect points' CPU per realisation, else its "
                     "perfect point's times the median imperfect / perfect ratio; x (N x "
                     "imperfect candidates) + the perfect points"}


def fmt_fixed(x, nd=3) -> str:
    """x with nd decimals, '-' for None (the report's lambdas)."""
    return "-" if x is None else f"{x:.{nd}f}"


def report(out: Path, candidates: dict, specs: dict, n: int, command: str) -> dict:
    """Write <out>/summary.json and <out>/README.md from the committed point files."""
    from dem.output.atomic import write_json

    points = collect(out, candidates, specs, n)
    scores = {c: score_candidate(points[c]) for c in candidates}
    selection = select(candidates, points, scores)
    cpu = sum(p.get("cpu_seconds") or 0.0 for c in points for p in points[c].values())
    est = estimate(points, specs, candidates, n)
    held = held_out_summary(out)
    summary = {"kind": "calibration", "issue": 13, "step": 1, "command": command,
               "realisations": n, "seeds": f"0..{n - 1} (perfect: 0 only, deterministic)",
               "candidates": candidates, "specimens": {s: {"case": rel(v["path"]),
                   "kind": v["kind"], "l_over_h": v["l_over_h"]}
                   for s, v in specs.items()},
               "targets": TARGETS, "points": points, "scores": scores,
               "selection": selection, "cpu_seconds_so_far": cpu, "estimate": est,
               "held_out": held}
    write_json(out / "summary.json", summary, indent=1)

    L = ["# Calibration on the Chapter 3 tilting tests (issue 13, step 1)", "",
         f"Generated by `{command}` (resumable: finished points are skipped, unfinished "
         "ensembles keep their finished realisations); `--report` rebuilds this page and "
         "summary.json from the committed point files "
         "`<candidate>/<specimen>/ensemble.json`.", "",
         "Each point: the small-brick tilt specimen of cases/tilt on a quasi-static tilt "
         "(studies/tilt/study.py `quasi_static_case`, `study_settings`) with the candidate's "
         "`imperfections:` (studies/calibration/candidates.yaml, where each magnitude comes from), "
         f"N = {n} realisations with seeds 0..{n - 1} (the perfect candidate is deterministic: "
         "one run), friction 0.81 and joint stiffness as in the case files.  lambda = tan(tilt "
         "angle at collapse), the median and 10-90 % band over the realisations; mechanisms: "
         "counts over the realisations (postprocess/mechanisms.py).  A point not finished shows "
         "as pending.  CPU: user + system seconds of the point's `dem ensemble` process tree "
         "(one worker, one Taichi thread), summed over the sessions that ran it.  Every point "
         f"ran on the engine's results revision {RESULTS_REVISION} (dem.engine.RESULTS_REVISION, "
         "part of the resume fingerprint: a point of another revision is run again).", "",
         "How the frozen set will be chosen from these points was fixed before the grid "
         "finished: [SELECTION.md](SELECTION.md).  Points of earlier revisions were withdrawn; "
         "what they showed and why: [HISTORY.md](HISTORY.md).", ""]
    L += ["## Targets (../shared/REFERENCE.md) and their strength", "",
          "| target | kind | strength | what |", "|---|---|---|---|"]
    for t in TARGETS:
        L.append(f"| {t['id']} | {t['kind']} | {t['strength']} | {t['text']} |")
    L += [""] + selection_lines(selection) + held_out_lines(held)
    for c, params in candidates.items():
        pts, sc = points[c], scores[c]
        L += [f"## {c}", "", "`" + json.dumps(params) + "`", "",
              "| specimen | L/H | done | median lambda | vs perfect | 10-90 % | mechanisms | "
              "median overturning fraction | CPU s | CPU s / realisation |",
              "|---|---|---|---|---|---|---|---|---|---|"]
        for s in specs:
            p = pts[s]
            done = f"{p.get('n_ok', 0)}/{p.get('n_realisations') or '-'}"
            cpu_s = p.get("cpu_seconds")
            per = (cpu_s / p["n_realisations"]) if cpu_s and p.get("n_realisations") else None
            if summary_finished(p):
                band = f"{fmt_fixed(p.get('lambda_q10'), 4)} - {fmt_fixed(p.get('lambda_q90'), 4)}"
                mech = [f"{k} {v}" for k, v in (p.get("mechanisms") or {}).items()]
                if p.get("no_collapse"):
                    mech.append(f"no collapse {p['no_collapse']}")
                if p.get("lone_block"):
                    mech.append("one block alone: " + ", ".join(
                        f"{n} at {fmt_fixed(lam, 3)}" for n, lam in p["lone_block"]))
                mech = ", ".join(mech) or "-"
                if p.get("smoke"):
                    done += " (smoke: steps capped)"
                ref = points.get("perfect", {}).get(s, {})
                vs = (f"{100 * (p['lambda_median'] / ref['lambda_median'] - 1):+.1f} %"
                      if c != "perfect" and summary_finished(ref) and ref.get("lambda_median")
                      and p.get("lambda_median") is not None else "-")
                L.append(f"| {s} | {fmt_fixed(p.get('l_over_h'), 2)} | {done} | "
                         f"{fmt_fixed(p.get('lambda_median'), 4)} | {vs} | {band} | {mech} | "
                         f"{fmt_fixed(p.get('overturning_fraction_median'), 2)} | "
                         f"{fmt_fixed(cpu_s, 0)} | {fmt_fixed(per, 0)} |")
            elif p.get("stale"):
                L.append(f"| {s} | {fmt_fixed(p.get('l_over_h'), 2)} | - | pending (the committed "
                         "point is of an earlier revision or case: not shown, see HISTORY.md) | "
                         "- | pending | pending | pending | - | - |")
            else:
                L.append(f"| {s} | {fmt_fixed(p.get('l_over_h'), 2)} | {done} | pending | - | "
                         f"pending | pending | pending | {fmt_fixed(cpu_s, 0)} | - |")
        L += ["", "| check | kind | status | detail |", "|---|---|---|---|"]
        for k, v in sc["invariants"].items():
            L.append(f"| {k} | invariant | {v['status']} | {_detail(k, v)} |")
        for k, v in sc["thesis"].items():
            L.append(f"| {k} | thesis | {v['status']} | {_detail(k, v)} |")
        fam = "; ".join(
            f"L/H {r['l_over_h']}: FaMIVE {r['famive']}, DEM "
            + (f"{r['median']:.3f} ({100 * r['relative_difference']:+.0f} %, "
               + ("deterministic" if r["in_band"] is None else
                  f"{'in' if r['in_band'] else 'outside'} the band") + ")"
               if "median" in r else "pending")
            for r in sc["famive"])
        L += [f"| famive | thesis, MODEL values, not scored | - | {fam or '-'} |", ""]
    commits = sorted({(p.get("commit"), p.get("dirty")) for c in points
                      for p in points[c].values() if p.get("commit")})
    L += ["## Code", "", "The points were computed by commit(s) " + (", ".join(
        f"{c[:7]}" + (" (with uncommitted changes in dem/, postprocess/, studies/ or cases/)" if d else "")
        for c, d in commits) or "-") + " (each point file's `calibration.source`).", ""]
    L += ["## CPU", "",
          f"CPU so far: {cpu:.0f} s ({cpu / 3600:.2f} h) over the finished and partial points."]
    per = est["cpu_seconds_per_realisation"]
    L += ["", "| specimen | CPU s per imperfect realisation | from |", "|---|---|---|"]
    L += [f"| {s} | {fmt_fixed(v, 0)} | {est['how'][s]} |" for s, v in per.items()]
    g = est["grid_cpu_seconds"]
    L += ["", "Estimated CPU of the whole grid (" + f"{len(candidates)} candidates x "
          f"{len(specs)} specimens, N = {n}): "
          + (f"{g:.0f} s = {g / 3600:.1f} h, of which {est['finished_cpu_seconds']:.0f} s "
             "are done" if g else "not yet (a specimen has no finished point)")
          + f"; {est['basis']}.", ""]
    (out / "README.md").write_text("\n".join(L) + "\n")
    return summary


def _detail(key: str, v: dict) -> str:
    s = v.get("status")
    if s == "n/a":
        return v.get("why", "")
    if s == "pending":
        w = v.get("waiting_for") or [r["specimen"] for r in v.get("rows", [])
                                     if r.get("status") == "pending"] or v.get("specimen")
        return f"waiting for {w}" if w else ""
    if key == "sliding-invariant":
        return (f"{v['specimen']}: median {fmt_fixed(v.get('median'), 4)} vs mu {v.get('mu')} "
                f"({100 * v['relative_error']:+.1f} %, tolerance 3 %), band "
                f"{fmt_fixed(v['band'][0], 4)} - {fmt_fixed(v['band'][1], 4)}, modal "
                f"{v.get('modal_mechanism')}" if "relative_error" in v else v.get("why", ""))
    if key == "mechanism-sequence":
        seq = ", ".join(f"{r['l_over_h']}: {r['modal']} ({fmt_fixed(r['overturning_fraction'], 2)})"
                        for r in v["series"])
        return seq + ("; " + "; ".join(v["problems"]) if v["problems"] else "")
    if key in ("in-plane-mechanisms", "oop-mechanisms"):
        return "; ".join(f"{r['specimen']}: {r.get('modal', 'pending')} ({r['status']})"
                         for r in v["rows"])
    if key == "stagger-trend":
        return ", ".join(f"{n}: {fmt_fixed(m, 4)}" for n, m in zip(v["specimens"], v["medians"]))
    return json.dumps(v)


