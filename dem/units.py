"""The one table of units of the numbers a run writes: summary.json, frames.npz, instruments.npz.

SI throughout (the case files' units, docs/engine.md): m, s, kg, N, J, Pa; angles in degrees
where a key says ``_deg`` (the table angle, the collapse angle) and radians in the engine's
state (``omega`` rad/s).  "-" is a dimensionless number (a ratio, a load factor, a count, a
block index, a unit vector); "" a text.

A number's unit is found, in this order, by

1. its dotted path in :data:`SUMMARY_UNITS` / :data:`FRAMES_UNITS` / :data:`INSTRUMENTS_UNITS`
   (a list's items are ``[]``: ``collapse.angles[].motion_m``; ``*`` matches one key), then
2. the unit its key's name ends with (:data:`SUFFIXES`: ``max_penetration_m`` is in m,
   ``peak_acceleration_m_s2`` in m/s2, ``normal_stiffness_Pa_m`` in Pa/m), then
3. a dimensionless name (:data:`DIMENSIONLESS_WORDS`: ``n_*``, ``*_ratio``, ``*fraction``,
   ``relative``, ``load_factor`` ...).

The files carry it: summary.json ``units`` ({path: unit} for every number in it, paths as
above), frames.npz and instruments.npz ``units`` (a [K, 2] array of (key, unit) rows:
``dict(np.load(f)["units"])``).  These are added keys; no other key changed.
"""

from __future__ import annotations

import re

import numpy as np

# explicit units of summary.json numbers whose key does not say it (dotted paths, [] list items)
SUMMARY_UNITS: dict[str, str] = {
    "n_blocks": "-",
    "dt": "s",
    "dt_critical": "s",
    "steps": "-",
    "sim_time": "s",
    "wall_seconds": "s",
    "compile_seconds": "s",
    "cpu_seconds": "s",
    "skin": "m",
    "output_interval": "s",
    "results_revision": "-",
    "step_limit": "-",
    "brick_steps_per_second": "1/s",
    "neighbour_rebuilds": "-",
    "n_pairs": "-",
    "n_contact_points": "-",
    "vtk_frames": "-",
    "vtk_bytes": "B",
    "energy.*": "J",
    "dt_changes[].t": "s",
    "dt_changes[].step": "-",
    "dt_changes[].old_dt": "s",
    "dt_changes[].new_dt": "s",
    "dt_changes[].*dt*": "s",
    "material.friction": "-",
    "material.base_friction": "-",
    "material.damping": "-",
    "material.normal_stiffness": "Pa/m",
    "material.shear_stiffness": "Pa/m",
    "*normal_stiffness": "Pa/m",       # material.materials[], joints.pairs[] too
    "*shear_stiffness": "Pa/m",
    "*max_closure": "m",
    "*closure_limit": "-",             # a fraction of max_closure
    "*closure_fraction": "-",          # summary.json hyperbolic_closure: a fraction of d_max
    "loading.axis[]": "-",
    "loading.direction[]": "-",
    "loading.load_direction[]": "-",
    "loading.cycles": "-",
    "loading.samples": "-",
    "loading.steps": "-",
    "loading.steps[].cycles_run": "-",   # a stepped shake's steps (dem.table_motion)
    "loading.steps[].end_side": "-",
    "collapse.load_factor": "-",
    "collapse.relaxations": "-",
    "collapse.relax_steps": "-",
    "collapse.n_moved": "-",
    "collapse.dynamic_turns": "-",
    "collapse.frame": "-",
    "collapse.criterion.tolerance": "-",
    "collapse.criterion.local_damping": "-",
    "collapse.criterion.increment_deg": "deg",
    "collapse.criterion.onset_speed": "m/s",
    "collapse.criterion.confirm": "m",
    "collapse.criterion.stop": "m",
    "collapse.criterion.after": "s",
    "collapse.moved_blocks[]": "-",
    "collapse.*blocks[]": "-",
    "mechanism.*blocks[]": "-",
    "mechanism.*.blocks[]": "-",
    "mechanism.*.n_blocks": "-",
    "mechanism.*.n_candidates": "-",
    "joints.*.steps_factor": "-",
    "joints.elastic_offset.direction[]": "-",
    "imperfections.seed": "-",
    "settling.steps": "-",
    "settling.local_damping": "-",
    "settling.criteria.looks": "-",
    "settling.criteria.unbalanced_force_ratio": "-",
    "resumed[].step": "-",
}

# frames.npz (dem/run/record.py; tilt runs add tilt_angle)
FRAMES_UNITS: dict[str, str] = {
    "t": "s", "pos": "m", "quat": "-", "vel": "m/s", "omega": "rad/s", "base_disp": "m",
    "tilt_angle": "deg",
}

# instruments.npz (dem/instruments.py)
INSTRUMENTS_UNITS: dict[str, str] = {
    "t": "s", "disp": "m", "vel": "m/s", "acc": "m/s2", "table_disp": "m", "table_acc": "m/s2",
    "table_vel": "m/s", "names": "", "kind": "", "group": "", "block": "-", "point": "m",
    "direction": "-",
}

# key endings and their units, longest first (so _m_s2 wins over _s2 and _m)
SUFFIXES: tuple[tuple[str, str], ...] = tuple(sorted({
    "_m": "m", "_mm": "mm", "_s": "s", "_seconds": "s", "_deg": "deg", "_rad": "rad",
    "_hz": "Hz", "_Hz": "Hz", "_kg": "kg", "_J": "J", "_N": "N", "_Pa": "Pa",
    "_m_s": "m/s", "_m_s2": "m/s2", "_rad_s": "rad/s", "_deg_per_s": "deg/s",
    "_Pa_m": "Pa/m", "_pa_per_m": "Pa/m", "_kg_m3": "kg/m3", "_per_m": "1/m", "_bytes": "B",
    "_m2": "m2", "_m3": "m3", "_J_per_kg": "J/kg",
}.items(), key=lambda kv: -len(kv[0])))

# names of dimensionless numbers (matched against the last key of a path, list marks removed)
DIMENSIONLESS_WORDS = re.compile(
    r"(^n_|^n$|_count$|^count|ratio|fraction|relative|factor|amplification|^mu$|friction|"
    r"^seed$|(^|_)steps$|^step$|^index$|^frame$|^block$|^blocks$|^ok$|^detected$|^survived$|tolerance|"
    r"^damping$|_damping$|^revision$|^looks$|^relaxations$|^attempts$|^candidates$|share$|"
    r"cycles?$|^courses?$|_listed$)")


def _last_key(path: str) -> str:
    return path.rsplit(".", 1)[-1].replace("[]", "")


def unit_of(path: str, table: dict[str, str | None] | None = None) -> str | None:
    """The unit of the number at dotted ``path`` (list items as ``[]``), by the explicit
    ``table`` (default :data:`SUMMARY_UNITS`), then its key's ending, then a dimensionless name;
    None when none of them says."""
    table = SUMMARY_UNITS if table is None else table
    if path in table and table[path] is not None:
        return table[path]
    for pattern, unit in table.items():
        if unit is not None and "*" in pattern and \
                re.fullmatch(re.escape(pattern).replace(r"\*", ".*"), path):
            return unit
    key = _last_key(path)
    for suffix, unit in SUFFIXES:
        if key.endswith(suffix):
            return unit
    if DIMENSIONLESS_WORDS.search(key):
        return "-"
    return None


def _known(unit: str | None) -> str:
    return "?" if unit is None else unit  # "" (a text) is a known unit


def numeric_paths(data, prefix: str = "") -> list[str]:
    """The dotted paths (list items ``[]``, each path once, in first-seen order) of every
    number in a JSON-like ``data`` (bools are not numbers; the ``units`` block is skipped)."""
    seen: dict[str, None] = {}

    def walk(v, path):
        if isinstance(v, bool) or v is None or isinstance(v, str):
            return
        if isinstance(v, (int, float)):
            seen.setdefault(path, None)
        elif isinstance(v, dict):
            for k, x in v.items():
                if not path and k == "units":
                    continue
                walk(x, f"{path}.{k}" if path else str(k))
        elif isinstance(v, (list, tuple)):
            for x in v:
                walk(x, f"{path}[]")

    walk(data, prefix)
    return list(seen)


def summary_units(summary: dict) -> dict[str, str]:
    """summary.json's ``units``: {path: unit} for every number in ``summary``; a number whose
    unit the table does not know gets "?" (tests/test_units.py keeps that from happening)."""
    return {p: _known(unit_of(p)) for p in numeric_paths(summary)}


def npz_units(keys, table: dict[str, str]) -> np.ndarray:
    """The ``units`` array of an npz file holding ``keys``: [K, 2] rows (key, unit), "?" for a
    key the table and the suffix rules do not know."""
    rows = [(k, _known(unit_of(k, table))) for k in keys if k != "units"]
    return np.array(rows, dtype=str).reshape(-1, 2)
