"""Statistics of an ensemble of realisations: ``dem ensemble`` and
``dem sweep --realisations``.

Each realisation is one run of the same case with another ``imperfections.seed``.  From its
record (dem.batch: status, summary.json, and for a shaking run the sweep's compact analysis)
:func:`realisation_scalars` takes the scalar results: the load factor lambda and the mechanism of
a tilt, the amplifications, lags and excited bricks of a shaking run, and whether it survived
(no collapse detected; for a shaking run analysed by postprocess.survival, its verdict:
standing, local collapse or collapse, and the number of fallen bricks).  A tilt whose collapse
onset could not be resolved (dem.collapse: ``onset_resolved`` false) has no lambda: it is left
out of the lambda statistics and counted in ``n_onset_unresolved``, never read as lambda = 0.  :func:`statistics` gives, for each scalar, the median, the 10 % and
90 % quantiles (numpy's default linear interpolation between order statistics), the mean and
the population standard deviation (ddof = 0) over the realisations that have it; counts of each
mechanism and of failed realisations complete the summary.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from dem.output.plotting import agg_pyplot

QUANTILES = (0.1, 0.9)
NOT_RESULTS = {"seed"}  # numbers of a realisation's row that are not results


def _finite(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def realisation_scalars(record: dict) -> dict:
    """The scalar results of one realisation's record (module docstring)."""
    out: dict = {"status": record.get("status", "pending")}
    summ = record.get("summary") or {}
    col = summ.get("collapse") or {}
    if "load_factor" in col:
        out["lambda"] = col.get("load_factor") if col.get("detected") else None
        out["angle_deg"] = col.get("angle_deg") if col.get("detected") else None
        if col.get("detected") and col.get("onset_resolved") is False:
            # a collapse whose onset could not be resolved (dem.collapse) has no lambda: it
            # is left out of the statistics and counted, never read as lambda = 0
            out["lambda"] = out["angle_deg"] = None
            out["onset_unresolved"] = col.get("onset_note") or "onset not resolved"
    mech = summ.get("mechanism")
    if isinstance(mech, dict) and mech.get("mechanism") is not None:
        out["mechanism"] = str(mech["mechanism"])
    elif isinstance(mech, str):
        out["mechanism"] = mech
    if col:
        out["survived"] = not bool(col.get("detected"))
    post = record.get("post") or {}
    if post.get("analysis_status") == "ok":
        for key, val in (post.get("amplification") or {}).items():
            if _finite(val):
                out[f"amplification_{key}"] = val
        for key, val in (post.get("lag") or {}).items():
            lag = val.get("s") if isinstance(val, dict) else val
            if _finite(lag):
                out[f"lag_{key}_s"] = lag
        exc = (post.get("excited") or {}).get("n_excited")
        if _finite(exc):
            out["excited_bricks"] = exc
        if post.get("collapse_suspected") is not None:
            out["survived"] = not bool(post["collapse_suspected"])
        surv = post.get("survival") or {}
        if surv.get("verdict") is not None:  # postprocess.survival: every brick, not the centre
            out["survival"] = surv["verdict"]
            out["fallen_bricks"] = surv.get("n_fallen")
            out["survived"] = surv["verdict"] == "standing"
    settling = summ.get("settling") or {}
    if _finite(settling.get("largest_settlement_m")):
        out["largest_settlement_m"] = settling["largest_settlement_m"]
    return out


def statistics(values) -> dict:
    """n, median, q10, q90, mean, std (population, ddof = 0) of the finite values; n = 0 and
    None for the rest when there are none."""
    v = np.array([x for x in values if _finite(x)], dtype=np.float64)
    if v.size == 0:
        return {"n": 0, "median": None, "q10": None, "q90": None, "mean": None, "std": None}
    q10, q90 = np.quantile(v, QUANTILES)
    return {"n": int(v.size), "median": float(np.median(v)), "q10": float(q10),
            "q90": float(q90), "mean": float(v.mean()), "std": float(v.std())}


def aggregate(scalars: list[dict]) -> dict:
    """Statistics of every numeric scalar over the realisations that finished, counts of each
    mechanism, of survivals and of failures."""
    ok = [s for s in scalars if s.get("status") == "ok"]
    keys = sorted({k for s in ok for k, v in s.items() if _finite(v) and k not in NOT_RESULTS})
    out = {"n_realisations": len(scalars), "n_ok": len(ok),
           "n_failed": sum(1 for s in scalars if s.get("status") == "failed"),
           "n_pending": sum(1 for s in scalars if s.get("status") not in ("ok", "failed")),
           "statistics": {k: statistics(s.get(k) for s in ok) for k in keys}}
    mechs: dict[str, int] = {}
    for s in ok:
        if "mechanism" in s:
            mechs[s["mechanism"]] = mechs.get(s["mechanism"], 0) + 1
    out["mechanisms"] = dict(sorted(mechs.items()))
    unresolved = [s for s in ok if s.get("onset_unresolved")]
    if unresolved:
        out["n_onset_unresolved"] = len(unresolved)
        out["onset_unresolved_seeds"] = [s.get("seed") for s in unresolved]
    verdicts = [s["survival"] for s in ok if s.get("survival") is not None]
    if verdicts:
        from postprocess.survival import count_verdicts

        out["survival"] = count_verdicts(verdicts)
    surv = [s["survived"] for s in ok if "survived" in s]
    if surv:
        out["survived"] = int(sum(surv))
        out["collapsed"] = len(surv) - int(sum(surv))
    return out


def plot_lambda(scalars: list[dict], path: Path, title: str = "") -> bool:
    """Histogram of lambda over the realisations, median and 10-90 % band marked."""
    lam = [s["lambda"] for s in scalars if s.get("status") == "ok" and _finite(s.get("lambda"))]
    if not lam:
        return False
    plt = agg_pyplot()

    from dem.output.atomic import savefig

    st = statistics(lam)
    fig, ax = plt.subplots(figsize=(6, 3.6))
    ax.hist(lam, bins=max(5, min(30, len(lam) // 2)), color="0.7", edgecolor="0.3")
    ax.axvline(st["median"], color="C3", label=f"median {st['median']:.4f}")
    ax.axvspan(st["q10"], st["q90"], color="C0", alpha=0.2,
               label=f"10-90 %: {st['q10']:.4f} - {st['q90']:.4f}")
    ax.set_xlabel("load factor lambda = tan(collapse angle)")
    ax.set_ylabel("realisations")
    ax.set_title(title or f"{len(lam)} realisations")
    ax.legend(fontsize=8)
    fig.tight_layout()
    savefig(fig, path, dpi=110)
    plt.close(fig)
    return True


def plot_amplification_band(curves: dict[float, list[float]], path: Path, quantity: str,
                            title: str = "") -> bool:
    """Amplification against frequency: median over the realisations with the 10-90 % band."""
    freqs = sorted(f for f, v in curves.items() if any(_finite(x) for x in v))
    if not freqs:
        return False
    plt = agg_pyplot()

    from dem.output.atomic import savefig

    stats = [statistics(curves[f]) for f in freqs]
    fig, ax = plt.subplots(figsize=(6, 3.6))
    ax.fill_between(freqs, [s["q10"] for s in stats], [s["q90"] for s in stats], color="C0",
                    alpha=0.25, label="10-90 % of the realisations")
    ax.plot(freqs, [s["median"] for s in stats], "o-", color="C0", label="median")
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel(f"amplification of {quantity}")
    ax.set_title(title)
    ax.legend(fontsize=8)
    fig.tight_layout()
    savefig(fig, path, dpi=110)
    plt.close(fig)
    return True
