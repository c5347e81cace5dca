"""Write docs/case-reference.md, the reference of every case-file field, from the schema itself.

The reference is generated from the pydantic models (through their JSON schema: the same one
``dem schema`` writes), so it cannot drift from what ``dem check`` accepts: every field with its
type, its default (or "required"), its bounds and its description, whose text gives the unit
(the models write it as ", m", "Pa/m", "degrees" ... at the end of each description).

    python tools/case_reference.py            # rewrite docs/case-reference.md
    python tools/case_reference.py --check    # exit 1 if the committed file is stale

``tests/test_docs_paths.py`` runs the check.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import deque
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TARGET = ROOT / "docs" / "case-reference.md"
COMMAND = "python tools/case_reference.py"

HEADER = f"""# Case file reference

Generated from the schema by `{COMMAND}` (do not edit by hand; `tests/test_docs_paths.py`
fails when this page differs from what the schema gives).  How to write a case, with the
shipped cases as examples: [user-guide.md](user-guide.md).

SI units everywhere (m, kg, s, N, Pa), angles in degrees; the table is the plane z = 0, z up.
Each field's unit is at the end of its description.  Unknown keys are refused; numbers must be
finite.  "required" marks a field without a default.
"""


def _cell(text: str) -> str:
    """One markdown table cell: one line, pipes escaped."""
    return " ".join(str(text).split()).replace("|", "\\|")


def _ref_name(ref: str) -> str:
    return ref.rsplit("/", 1)[-1]


def _type(prop: dict, suffix: str = "") -> str:
    """A short type of a JSON-schema property: number, string, one of the enum's values, a
    list of ..., or a link to another model's table."""
    if "$ref" in prop:
        name = _ref_name(prop["$ref"])
        anchor = name.lower() + ("-" + "-".join(suffix.strip("() ").split()) if suffix else "")
        return f"[{name}](#{anchor})"
    if "const" in prop:
        return f"`{prop['const']}`"
    if "enum" in prop:
        return " or ".join(f"`{v}`" for v in prop["enum"])
    for key in ("anyOf", "oneOf"):
        if key in prop:
            parts = [_type(p, suffix) for p in prop[key] if p.get("type") != "null"]
            text = " or ".join(dict.fromkeys(parts))
            return text + (" or null" if any(p.get("type") == "null" for p in prop[key]) else "")
    kind = prop.get("type")
    if kind == "array":
        items = _type(prop.get("items", {}), suffix) if prop.get("items") else "any"
        n_min, n_max = prop.get("minItems"), prop.get("maxItems")
        size = (f" of {n_min}" if n_min is not None and n_min == n_max
                else f" ({n_min or 0}..{n_max if n_max is not None else ''} items)"
                if n_min is not None or n_max is not None else "")
        return f"list{size} of {items}"
    if kind == "object":
        extra = prop.get("additionalProperties")
        return f"map of {_type(extra, suffix)}" if isinstance(extra, dict) else "map"
    return {"number": "number", "integer": "integer", "string": "string",
            "boolean": "true/false"}.get(kind, kind or "any")


def _bounds(prop: dict) -> str:
    """The numeric and length bounds of a property (from every branch of a union)."""
    found = []
    for p in [prop, *prop.get("anyOf", []), *prop.get("oneOf", [])]:
        for key, sym in (("exclusiveMinimum", ">"), ("minimum", ">="), ("exclusiveMaximum", "<"),
                         ("maximum", "<=")):
            if key in p:
                found.append(f"{sym} {p[key]:g}")
        if "minLength" in p:
            found.append(f"length >= {p['minLength']}")
        if "pattern" in p:
            found.append(f"pattern `{p['pattern']}`")
    return ", ".join(dict.fromkeys(found))


def _refs(prop) -> list[str]:
    """Every model a property refers to, in order."""
    out = []
    if isinstance(prop, dict):
        if "$ref" in prop:
            out.append(_ref_name(prop["$ref"]))
        for value in prop.values():
            if isinstance(value, (dict, list)):
                out.extend(_refs(value))
    elif isinstance(prop, list):
        for value in prop:
            out.extend(_refs(value))
    return out


def render(schema: dict, title: str, root_path: str, suffix: str = "") -> str:
    """The tables of one schema: the root model first, then every model in the order a reader
    meets it, each headed by the first place it is used (e.g. ``loading.quasi_static``).
    ``suffix`` follows every heading (the two schemas share model names)."""
    defs = schema.get("$defs", {})
    root = {k: v for k, v in schema.items() if k != "$defs"}
    order: list[tuple[str, str, dict]] = [(title, root_path, root)]
    seen = {title}
    queue = deque([(root_path, root)])
    while queue:
        path, model = queue.popleft()
        for field, prop in model.get("properties", {}).items():
            sub = f"{path}.{field}" if path else field
            if prop.get("type") == "array" or "items" in prop:
                sub += "[]"
            for name in _refs(prop):
                if name not in seen and name in defs:
                    seen.add(name)
                    const = defs[name].get("properties", {}).get("type", {}).get("const")
                    where = f"{sub} (type: {const})" if const else sub
                    order.append((name, where, defs[name]))
                    queue.append((sub, defs[name]))
    out = []
    for name, where, model in order:
        out.append(f"### {name}{suffix}\n")
        if where:
            out.append(f"Used at `{where}`.\n")
        doc = model.get("description")
        if doc:
            out.append(" ".join(doc.split()) + "\n")
        required = set(model.get("required", []))
        rows = ["| field | type | default | bounds | description |", "|---|---|---|---|---|"]
        for field, prop in model.get("properties", {}).items():
            if field in required:
                default = "required"
            elif "default" in prop:
                default = f"`{json.dumps(prop['default'])}`"
            elif prop.get("type") == "array":
                default = "`[]`"
            elif prop.get("type") == "object":
                default = "`{}`"
            else:
                default = "(defaults of its fields)" if _refs(prop) else "-"
            rows.append("| " + " | ".join(_cell(c) for c in (
                f"`{field}`", _type(prop, suffix), default, _bounds(prop),
                prop.get("description", ""))) + " |")
        out.append("\n".join(rows) + "\n")
    return "\n".join(out)


def reference() -> str:
    """The whole page, as the schema gives it now."""
    from dem.case import case_json_schema
    from dem.rocking.schema import rocking_case_json_schema

    case = json.loads(case_json_schema())
    rocking = json.loads(rocking_case_json_schema())
    return "\n".join([
        HEADER,
        "## DEM case files (`dem run`, `dem check`, `dem sweep`, `dem ensemble`)\n",
        render(case, "Case", ""),
        "## Two-body rocking case files (`dem rocking`)\n",
        render(rocking, "RockingCase", "", suffix=" (two-body)"),
    ]).rstrip("\n") + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true",
                        help="do not write; exit 1 if docs/case-reference.md is stale")
    args = parser.parse_args(argv)
    text = reference()
    if args.check:
        current = TARGET.read_text() if TARGET.exists() else ""
        if current != text:
            print(f"{TARGET.relative_to(ROOT)} is stale: run `{COMMAND}`", file=sys.stderr)
            return 1
        return 0
    TARGET.write_text(text)
    print(f"wrote {TARGET.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
