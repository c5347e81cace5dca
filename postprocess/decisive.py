"""The numbers that decide a tilt's result, in words, for the result line of ``dem run``
(dem_cli.commands.run.result_line) and lean.png (postprocess.tilt.plot_lean): the closed form of
lone rigid blocks beside the run's lambda, with the error (summary.json ``reference``,
postprocess/lone_block.py), and the joint's elastic offset of tipping (summary.json
``joints.elastic_offset``, dem/compliance.py) with the way to remove it and what that costs.
Everything is read from a run's summary dict; nothing is recomputed.
"""

from __future__ import annotations

import json
from pathlib import Path

from dem.compliance import RIGID_OFFSET


def _pct(x: float) -> str:
    return f"{100.0 * x:+.2f} %"


def reference_text(summary: dict) -> str | None:
    """The closed form beside the run's lambda, for the result line: "closed form 0.500
    (sliding; lone rigid block: lambda = min(mu_base, b/h)), error +0.13 %"; None without
    one."""
    ref = summary.get("reference")
    col = summary.get("collapse") or {}
    if not ref or not col.get("detected") or col.get("load_factor") is None:
        return None
    lam, exact = col["load_factor"], ref["load_factor"]
    text = (f"closed form {exact:.3f} ({ref['mode']}; {ref['formula']}), error "
            f"{_pct(lam / exact - 1.0)}")
    el = ref.get("elastic_load_factor")
    if el is not None and abs(el / exact - 1.0) > 1e-3:
        text += (f"; {el:.3f} with the joint's elastic offset at kn = "
                 f"{ref['normal_stiffness_Pa_m']:.3g} Pa/m (error {_pct(lam / el - 1.0)})")
    return text


def elastic_offset_text(summary: dict) -> str | None:
    """The joint's elastic offset of tipping when it is larger than ``normal_stiffness: rigid``
    keeps it (dem.compliance, summary.json ``joints.elastic_offset``), with the way to remove it
    and its cost: steps scale as kn^(1/2) and the offset as kn^(-1/3), so bringing the offset r
    down to 0.5 % costs (r / 0.5 %)^(3/2) times the steps."""
    joints = summary.get("joints") or {}
    eo = joints.get("elastic_offset") or {}
    parts = [eo.get(k) or {} for k in ("block", "column")]
    r = max([p.get("relative") or 0.0 for p in parts] + [0.0])
    if str(joints.get("chosen", "")).startswith("rigid") or r <= RIGID_OFFSET * 1.01:
        return None
    return (f"elastic offset of tipping at kn = {joints.get('normal_stiffness_Pa_m', 0.0):.3g} "
            f"Pa/m: up to {100 * r:.1f} % below the rigid-block value (material.normal_stiffness: "
            f"rigid brings it to {100 * RIGID_OFFSET:.1f} %, at ~{(r / RIGID_OFFSET) ** 1.5:.0f}x "
            f"the steps)")


def threshold_text(summary: dict) -> str | None:
    """The collapse criterion lambda was read with (summary.json ``collapse``): a quasi-static
    tilt's bisection width and equilibrium tolerance (dem.run.quasi_static), a constant-rate
    tilt's onset speed and confirming motion (dem.collapse); None for no collapse."""
    col = summary.get("collapse") or {}
    if not col.get("detected"):
        return None
    crit = col.get("criterion") or {}
    if col.get("method") == "quasi_static" and crit:
        width = col.get("resolution_deg", crit.get("resolution_deg"))
        return (f"read as the last angle in equilibrium (unbalanced-force ratio < "
                f"{crit.get('tolerance'):g}), the first failing one {width:g} deg above")
    th = col.get("thresholds") or {}
    if th:
        return (f"read at the onset (the collapsing blocks last slower than "
                f"{th.get('onset_speed_m_s'):g} m/s before moving {th.get('confirm_m'):g} m)")
    return None


def decisive_numbers(summary: dict) -> list[str]:
    """What the result line of a tilt adds after lambda: the collapse criterion it was read
    with, the closed form where there is one (with the elastic value of a tipping block), and
    the joint's elastic offset where it matters (a tipping closed form, or no closed form) and
    ``rigid`` was not chosen."""
    out = [t for t in (threshold_text(summary),) if t is not None]
    ref = reference_text(summary)
    if ref is not None:
        out.append(ref)
    if ref is None or (summary.get("reference") or {}).get("mode") == "tipping":
        eo = elastic_offset_text(summary)
        if eo is not None:
            out.append(eo)
    return out


def lean_notes(run_dir) -> tuple[float | None, list[str]]:
    """(the closed form's angle in degrees or None, the :func:`decisive_numbers` lines) of a
    run directory's summary.json, for lean.png; (None, []) when it cannot be read."""
    try:
        summary = json.loads((Path(run_dir) / "summary.json").read_text())
    except (OSError, ValueError):
        return None, []
    ref = summary.get("reference") or {}
    return ref.get("angle_deg"), decisive_numbers(summary)
