"""``dem check CASE --show-defaults``: the case as it will run, every default filled in, as YAML
with each field's description (its unit) in a comment: what ``case.json`` of a run holds,
readable before the run.

The YAML loads back into the same case (tests/test_units.py checks the round trip): scalars,
lists and mappings are written as JSON flow values (valid YAML), sections and lists of sections
as blocks.
"""

from __future__ import annotations

import json

from pydantic import BaseModel

COMMENT_CHARS = 90  # a description longer than this is cut at a word (the schema has it whole)


def _comment(field) -> str:
    desc = " ".join((field.description or "").split())
    if not desc:
        return ""
    if len(desc) > COMMENT_CHARS:
        desc = desc[:COMMENT_CHARS].rsplit(" ", 1)[0] + " ..."
    return f"  # {desc}"


def _lines(model: BaseModel, indent: int) -> list[str]:
    pad = " " * indent
    out = []
    for name, field in type(model).model_fields.items():
        key = field.alias or name
        value = getattr(model, name)
        if isinstance(value, BaseModel):
            out.append(f"{pad}{key}:{_comment(field)}")
            out.extend(_lines(value, indent + 2))
        elif isinstance(value, list) and value and all(isinstance(v, BaseModel) for v in value):
            out.append(f"{pad}{key}:{_comment(field)}")
            for item in value:
                sub = _lines(item, indent + 4)
                out.append(f"{pad}  - {sub[0].lstrip()}")
                out.extend(sub[1:])
        else:
            dumped = json.dumps(_plain(value), allow_nan=False)
            out.append(f"{pad}{key}: {dumped}{_comment(field)}")
    return out


def _plain(value):
    """A field's value as JSON data (models inside dicts or tuples, enums, paths)."""
    if isinstance(value, BaseModel):
        return value.model_dump(mode="json", by_alias=True)
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, (str, int, float, bool)) or value is None:
        return value
    return json.loads(json.dumps(value, default=str))


def resolved_case_yaml(case: BaseModel) -> str:
    """The validated case, every default filled in, as commented YAML (module docstring)."""
    head = ["# the case as it runs: every default filled in (units in the comments; the full",
            "# descriptions: `dem schema`)"]
    return "\n".join(head + _lines(case, 0)) + "\n"
