"""The DEM's accelerations relative to the table against the thesis' values.

The thesis' a and da are almost certainly relative to the table (postprocess.shake
.relative_accelerations says why).  A run analysed by today's dem post carries them in analysis.json
(``axes.<axis>.relative_to_table``).  Older analysis.json files (every shipped sweep) hold only
the absolute ones; for them the relative amplification is estimated from the first harmonic:
with rho = ``h1_amplitude_ratio`` and phi = ``lag_deg`` of an absolute quantity (its phasor
against the same-kind table input is rho e^(-i phi)), the relative one's phasor is
rho e^(-i phi) - 1, so

    amplification(relative) ~ |rho e^(-i phi) - 1|                                (-)

(exact for a sinusoidal steady response; the thesis' peak-to-peak definition reads more where
the response has harmonics).

The thesis' values compared (../shared/thesis, REFERENCE.md): Model II y inside the effective
range 2.4 - 3.2 Hz about 2.0 for a (line 1017: "magnitudes around 2.0 for the directly measured
d, a and vs and around 2.5 for the derived va"), outside below 0.5 (line 1017); the front / back
facade amplification ratios of Tables 4.9 - 4.11 (lines 1177 - 1196: means 0.359 Model II y,
0.618 Model II x, 0.587 Model III y).

    python -m studies diagnosis relative results/shake        # prints a Markdown table
"""

from __future__ import annotations

import json
import math
from pathlib import Path

#: thesis front / back amplification ratio means (Tables 4.9 - 4.11, line 1177)
THESIS_FRONT_BACK = {("II", "y"): 0.359, ("II", "x"): 0.618, ("III", "y"): 0.587}
#: thesis amplification of a inside / outside the effective range, Model II y (line 1017)
THESIS_A_INSIDE, THESIS_A_OUTSIDE_MAX = 2.0, 0.5


def first_harmonic_relative(quantity: dict) -> float | None:
    """|rho e^(-i phi) - 1| of an analysis.json quantity entry (module docstring), or None."""
    rho, lag = quantity.get("h1_amplitude_ratio"), quantity.get("lag_deg")
    if rho is None or lag is None:
        return None
    z = rho * complex(math.cos(math.radians(lag)), -math.sin(math.radians(lag)))
    return abs(z - 1.0)


def relative_row(analysis: dict, axis: str | None = None) -> dict:
    """Relative amplifications of a, a_lp, a_front, da of one analysis.json: the recorded ones
    (``relative_to_table``) where present, else the first-harmonic estimates; the front / back
    ratio."""
    axis = axis or analysis.get("primary_axis") or next(iter(analysis["axes"]))
    ax = analysis["axes"][axis]
    rec = (ax.get("relative_to_table") or {}).get("amplification")
    if rec:
        out = {"source": "relative_to_table", **{k: rec.get(k) for k in
                                                 ("a_rel", "a_rel_lp", "a_front_rel", "da_rel")}}
    else:
        q = ax.get("quantities", {})
        out = {"source": "first-harmonic estimate"}
        for name, rel in (("a", "a_rel"), ("a_lp", "a_rel_lp"), ("a_front", "a_front_rel"),
                          ("da", "da_rel")):
            out[rel] = first_harmonic_relative(q[name]) if name in q else None
    back, front = out.get("a_rel"), out.get("a_front_rel")
    out["front_back"] = front / back if front is not None and back else None
    return out


def _fmt(x) -> str:
    return "-" if x is None else f"{x:.3g}"


def report(results: Path) -> str:
    """A Markdown table: every analysed point under ``results`` (sweep/f*Hz/analysis.json)."""
    lines = ["| sweep | f (Hz) | source | a_rel | a_rel_lp | a_front_rel | front/back | "
             "da_rel | a (absolute) |", "|---|---|---|---|---|---|---|---|---|"]
    for path in sorted(Path(results).glob("*/f*Hz/analysis.json")):
        data = json.loads(path.read_text())
        if not data.get("axes"):
            continue
        row = relative_row(data)
        a_abs = (data.get("amplification") or {}).get("a")
        lines.append(f"| {path.parent.parent.name} | {data['excitation']['frequency_hz']:g} | "
                     f"{row['source']} | {_fmt(row['a_rel'])} | {_fmt(row['a_rel_lp'])} | "
                     f"{_fmt(row['a_front_rel'])} | {_fmt(row['front_back'])} | "
                     f"{_fmt(row['da_rel'])} | {_fmt(a_abs)} |")
    lines.append("")
    lines.append(f"Thesis (Model II y): a about {THESIS_A_INSIDE:g} inside the effective range "
                 f"2.4 - 3.2 Hz, below {THESIS_A_OUTSIDE_MAX:g} outside (line 1017); front/back "
                 + ", ".join(f"Model {m} {a}: {v:g}" for (m, a), v in THESIS_FRONT_BACK.items())
                 + " (Tables 4.9 - 4.11).")
    return "\n".join(lines)
