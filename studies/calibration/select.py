"""The rule of results/calibration/SELECTION.md applied to the scored calibration points
(from the calibration to the freeze: which imperfection set is frozen).

The rule was committed before the grid finished; this module only executes it, so that the
choice is the same whoever reads the points:

1. **Rejected**: an imperfect candidate that fails an invariant (``sliding-invariant``,
   ``mechanism-sequence``, ``no-wings-lowest`` where applicable), or whose realisations on any
   specimen end in a collapse of one block alone in more than :data:`LONE_BLOCK_LIMIT` of the
   realisations, or that is still pending on any specimen.
2. **Ranked** by the number of thesis checks passed (:data:`THESIS_CHECKS`); the candidates with
   the most passes remain.
3. **Ties**: the bed unevenness closest to :data:`CENTRE_BED` on a log scale; between two equally
   far, the smaller one; at equal bed unevenness, the variant with size scatter and arris.
4. The **perfect** set is chosen only when every imperfect candidate is rejected.

A candidate pending on some specimen is not eligible (rule 1), but it could still outrank the
leader once finished.  So :func:`select` only calls a choice ``decided`` when no pending
candidate could outrank the leader even if every one of its pending checks passed: at most its
finished passes plus its pending thesis checks, compared with the leader by the same ranking.
The freeze (``python -m studies calibration --freeze``) is refused until the choice is decided.

Inputs are studies.calibration.report.collect (candidate -> specimen -> point_summary) and
``score_candidate`` results; nothing is run here.  Units: bed unevenness in m.
"""

from __future__ import annotations

import math

#: the thesis checks that rank the candidates (rule 2); FaMIVE is shown, never scored
THESIS_CHECKS = ("in-plane-mechanisms", "stagger-trend", "oop-mechanisms")
#: rule 1: a specimen whose realisations collapse as one block alone more often than this
LONE_BLOCK_LIMIT = 0.10
#: rule 3: the centre of the prior bracket of the bed unevenness (0.05-0.2 mm), m
CENTRE_BED = 1.0e-4


def is_perfect(params: dict) -> bool:
    """True when a candidate has no imperfection (every length zero): a deterministic model."""
    sizes = params.get("size_scatter") or [0.0, 0.0, 0.0]
    return not (params.get("bed_unevenness", 0.0) > 0 or params.get("arris", 0.0) > 0
                or any(s > 0 for s in sizes))


def has_scatter_and_arris(params: dict) -> bool:
    return bool(any(params.get("size_scatter") or [])) and params.get("arris", 0.0) > 0.0


def tie_key(params: dict) -> tuple:
    """Rule 3 as a sort key (smaller first): log distance of the bed unevenness from the
    bracket's centre, then the smaller bed unevenness, then scatter + arris before without."""
    bed = float(params.get("bed_unevenness", 0.0))
    dist = abs(math.log(bed / CENTRE_BED)) if bed > 0 else math.inf
    return (round(dist, 9), bed, 0 if has_scatter_and_arris(params) else 1)


def rank_key(passes: int, params: dict) -> tuple:
    """Rules 2 and 3 as one sort key: more thesis passes first, then :func:`tie_key`."""
    return (-passes, *tie_key(params))


def _lone_block_specimens(points: dict) -> list[dict]:
    """The finished specimens whose lone-block collapses exceed LONE_BLOCK_LIMIT."""
    out = []
    for s, p in points.items():
        if p.get("status") != "finished" or not p.get("n_ok"):
            continue
        frac = len(p.get("lone_block") or []) / p["n_ok"]
        if frac > LONE_BLOCK_LIMIT:
            out.append({"specimen": s, "fraction": frac})
    return out


def assess(points: dict, score: dict) -> dict:
    """One candidate under rules 1-2: status ``rejected`` (with the reasons), ``pending`` (no
    reason to reject it yet, a specimen still to run) or ``eligible``; its thesis passes, its
    pending thesis checks and the passes it could reach at best."""
    reasons = [f"invariant {k} fails" for k, v in score["invariants"].items()
               if v["status"] == "fail"]
    reasons += [f"{x['specimen']}: {100 * x['fraction']:.0f} % of the realisations collapse as "
                f"one block alone (> {100 * LONE_BLOCK_LIMIT:.0f} %)"
                for x in _lone_block_specimens(points)]
    pending_specimens = [s for s, p in points.items() if p.get("status") != "finished"]
    thesis = {k: score["thesis"][k]["status"] for k in THESIS_CHECKS}
    passes = sum(1 for v in thesis.values() if v == "pass")
    pending_checks = [k for k, v in thesis.items() if v == "pending"]
    status = "rejected" if reasons else ("pending" if pending_specimens else "eligible")
    return {"status": status, "reasons": reasons, "pending_specimens": pending_specimens,
            "thesis": thesis, "passes": passes, "pending_checks": pending_checks,
            "best_possible_passes": passes + len(pending_checks)}


def select(candidates: dict, points: dict, scores: dict) -> dict:
    """SELECTION.md applied: ``candidates`` name -> imperfection parameters; ``points``
    name -> specimen -> point_summary; ``scores`` name -> score_candidate.

    Returns {"decided", "chosen" (a name, or None while undecided), "leader", "ranking" (the
    eligible imperfect candidates, best first), "candidates" (name -> :func:`assess` plus
    ``could_outrank_leader`` for a pending one), "why" (one sentence)}."""
    rows = {c: assess(points[c], scores[c]) for c in candidates}
    imperfect = [c for c in candidates if not is_perfect(candidates[c])]
    perfect = [c for c in candidates if is_perfect(candidates[c])]
    for c in perfect:
        rows[c]["status"] = f"reference (rule 4; {rows[c]['status']})"
    eligible = sorted((c for c in imperfect if rows[c]["status"] == "eligible"),
                      key=lambda c: rank_key(rows[c]["passes"], candidates[c]))
    pending = [c for c in imperfect if rows[c]["status"] == "pending"]
    leader = eligible[0] if eligible else None
    lead_key = rank_key(rows[leader]["passes"], candidates[leader]) if leader else None
    for c in pending:
        best = rank_key(rows[c]["best_possible_passes"], candidates[c])
        rows[c]["could_outrank_leader"] = lead_key is None or best < lead_key
    contenders = [c for c in pending if rows[c]["could_outrank_leader"]]
    if leader is not None and not contenders:
        chosen, decided = leader, True
        why = (f"{leader}: no invariant failed, {rows[leader]['passes']} of "
               f"{len(THESIS_CHECKS)} thesis checks passed")
        ties = [c for c in eligible[1:] if rows[c]["passes"] == rows[leader]["passes"]]
        if ties:
            why += f"; tie with {ties} broken by rule 3 (bed unevenness closest to 0.1 mm)"
        if pending:
            why += (f"; {pending} still pending, but could not outrank it even with every "
                    "pending check passed")
    elif leader is None and not pending:
        chosen, decided = (perfect[0] if perfect else None), bool(perfect)
        why = "every imperfect candidate is rejected: rule 4 freezes the perfect set"
    else:
        chosen, decided = None, False
        why = ((f"the leader is {leader}" if leader else "no candidate is eligible yet")
               + f"; {contenders} are pending and could still outrank "
               + ("it" if leader else "any leader"))
    return {"decided": decided, "chosen": chosen, "leader": leader, "ranking": eligible,
            "candidates": rows, "why": why}


def selection_lines(sel: dict) -> list[str]:
    """The report's section on the selection (markdown lines)."""
    L = ["## Selection (SELECTION.md applied by studies/calibration/select.py)", "",
         ("**Decided: " + str(sel["chosen"]) + ".** " if sel["decided"] else "**Not decided.** ")
         + sel["why"] + ".", "",
         "| candidate | status | thesis checks passed | failed | pending | best possible | "
         "reasons / pending specimens |", "|---|---|---|---|---|---|---|"]
    for c, r in sel["candidates"].items():
        detail = "; ".join(r["reasons"]) or (", ".join(r["pending_specimens"]) or "-")
        extra = ""
        if "could_outrank_leader" in r:
            if sel["leader"] is None:
                extra = " (could still be chosen)"
            else:
                extra = " (could outrank the leader)" if r["could_outrank_leader"] else \
                    " (cannot outrank the leader)"
        failed = [k for k, v in r["thesis"].items() if v == "fail"]
        L.append(f"| {c} | {r['status']}{extra} | {r['passes']} | {', '.join(failed) or '-'} | "
                 f"{', '.join(r['pending_checks']) or '-'} | {r['best_possible_passes']} | "
                 f"{detail} |")
    return L + [""]


class FreezeRefused(RuntimeError):
    """The freeze cannot be written: the choice is undecided, or another set is already frozen."""


def frozen_yaml(name: str, params: dict, why: str, today: str) -> str:
    """The text of studies/calibration/frozen.yaml for the chosen candidate (the format
    studies.prediction.plan.load_frozen reads: ``imperfections:`` plus provenance)."""
    import yaml

    body = {"imperfections": {k: params[k] for k in ("bed_unevenness", "face_shape",
                                                     "size_scatter", "arris")},
            "candidate": name, "derived_in": "results/calibration/README.md",
            "frozen_on": today, "note": why}
    head = ("# The frozen imperfection set (issue 13 step 2): chosen from the Chapter 3 calibration\n"
            "# by the rule of results/calibration/SELECTION.md (postprocess/calibration_select.py),\n"
            "# written by `python -m studies calibration --out results/calibration "
            "--freeze`.\n"
            "# Lengths in metres.  One set for every model; friction and joint stiffness stay the\n"
            "# case files' values.  Never edited after the freeze: the prediction names the commit\n"
            "# that last changed this file.\n")
    return head + yaml.safe_dump(body, sort_keys=False, width=100)


def freeze(sel: dict, candidates: dict, path, today: str) -> bool:
    """Write the decided choice to ``path``; True when written, False when the same set is already
    there.  FreezeRefused while the choice is undecided or when ``path`` holds another set."""
    import yaml
    from pathlib import Path

    path = Path(path)
    if not sel["decided"]:
        raise FreezeRefused(f"no freeze, the choice is undecided: {sel['why']}")
    name = sel["chosen"]
    params = candidates[name]
    if path.exists():
        old = yaml.safe_load(path.read_text()) or {}
        same = old.get("candidate") == name and all(
            old.get("imperfections", {}).get(k) == params[k] for k in params)
        if same:
            return False
        raise FreezeRefused(f"{path} already holds the frozen set {old.get('candidate')!r}; the "
                            f"freeze happens once (the rule now chooses {name!r}: say why in "
                            "results/calibration/HISTORY.md before replacing it by hand)")
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(frozen_yaml(name, params, sel["why"], today))
    return True
