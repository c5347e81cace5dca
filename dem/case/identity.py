"""What makes two cases the same case, for the records that outlive a code change: a study's
resume fingerprint, a sweep point's reuse (dem_cli.commands.sweep.finished_run), a restart point
(dem.run.resume).

A case field added to the schema after runs were recorded, left at the value that reproduces
the behaviour from before it existed, must not turn every recorded run into "another case"
(they would all run again: E4, the calibration and the prediction fingerprint the case's
JSON).  ``LATER_FIELDS`` names each such field with that neutral value; :func:`identity_json`
leaves a field out while it holds it, so a case's identity is its JSON as the schema of the
time the run was recorded would have written it (checked against the recorded fingerprints
of results/diagnosis/e4 in tests/test_case_identity.py).  Add a field here when it is added
to the schema with a default that changes nothing.
"""

from __future__ import annotations

import json

# (section, field) -> the value that reproduces the behaviour from before the field existed
LATER_FIELDS = {
    ("solver", "overlap_reuse"): 0.0,   # off: the full narrow phase every step
    # the normal dashpot as a fraction of critical (material.damping), the law of before
    ("material", "normal_damping"): "critical",
    ("material", "damping_time"): None,
}


def _neutral(case) -> dict:
    out: dict = {}
    for (section, name), neutral in LATER_FIELDS.items():
        part = getattr(case, section, None)
        if part is not None and getattr(part, name, None) == neutral:
            out.setdefault(section, set()).add(name)
    return out


def identity_json(case) -> str:
    """The case's JSON (pydantic's ``model_dump_json``) without the later fields that hold
    their neutral value: what resume fingerprints hash."""
    return case.model_dump_json(exclude=_neutral(case) or None)


def same_case(recorded: dict, case) -> bool:
    """Whether ``recorded`` (a case.json or a restart point's case, as a dict) is ``case``:
    equal once the later fields at their neutral values are left out of both."""
    def strip(d: dict) -> dict:
        d = json.loads(json.dumps(d))
        for (section, name), neutral in LATER_FIELDS.items():
            part = d.get(section)
            if isinstance(part, dict) and part.get(name, neutral) == neutral:
                part.pop(name, None)
        return d

    return strip(recorded) == strip(json.loads(case.model_dump_json()))
