"""Error messages for case files that name the field path and the YAML line.

pydantic reports a location such as ``('loading', 'shake', 'frequency')``: the field path plus the
tags it inserts for unions (``shake``, ``float``, ``BrickSpec`` ...).  The YAML node tree (from
``yaml.compose``, whose nodes carry start marks) is walked along that location to find the line;
the tags are dropped from the printed path because they are not keys of the file.  For a value
given as text where a number is expected ("20 mm"), the field's description (which states the
unit) is added, since case files take plain numbers in SI units.

Output, one line per problem::

    case.yaml:12: loading.frequency: Input should be greater than 0
"""

from __future__ import annotations

import types
import typing
from typing import Any

import yaml
from pydantic import BaseModel, ValidationError

_NUMBER_ERRORS = {"float_parsing", "float_type", "int_parsing", "int_type", "int_from_float"}


class DuplicateKeyError(ValueError):
    """A key given twice in one mapping; ``line`` (1-based) of the second, ``message`` without
    the line."""

    def __init__(self, message: str, line: int | None = None):
        super().__init__(f"line {line}: {message}" if line else message)
        self.message, self.line = message, line


# libyaml's loader where PyYAML was built with it (10-20 x faster on a large explicit scene),
# else the pure-Python one: the same nodes and data
SAFE_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
# the most values a case file may stand for once its aliases are expanded: a 20 000-block
# explicit scene (the default size limit) is ~ 15 values a block, 300 000; a few nested aliases
# can stand for billions ("billion laughs"), which every later walk of the data would visit
MAX_EXPANDED_VALUES = 5_000_000


class AliasError(ValueError):
    """Aliases that refer to themselves, or that expand beyond MAX_EXPANDED_VALUES; ``line``
    (1-based) of the anchor, ``message`` without the line."""

    def __init__(self, message: str, line: int | None = None):
        super().__init__(f"line {line}: {message}" if line else message)
        self.message, self.line = message, line


def compose(text: str) -> yaml.Node | None:
    """The YAML node tree of ``text`` (safe loader); raises DuplicateKeyError for a key given twice
    in one mapping (yaml.safe_load would silently keep the last one), AliasError for an anchor
    that contains itself or aliases that expand beyond MAX_EXPANDED_VALUES."""
    node = yaml.compose(text, Loader=SAFE_LOADER)
    check_nodes(node)
    return node


def load(text: str):
    """(node tree, data) of ``text``, parsed once: :func:`compose`, then the data constructed
    from its nodes (what yaml.safe_load gives)."""
    node = compose(text)
    if node is None:
        return None, None
    loader = SAFE_LOADER("")
    try:
        return node, loader.construct_document(node)
    finally:
        loader.dispose()


def _children(node) -> list:
    if isinstance(node, yaml.MappingNode):
        return [x for kv in node.value for x in kv]
    if isinstance(node, yaml.SequenceNode):
        return list(node.value)
    return []


def check_nodes(root) -> None:
    """Duplicate keys, self-referring anchors and the expanded size, in one walk that visits each
    node once (an alias is the same node object as its anchor: a walk that followed every alias
    would take as long as the expanded document).  Iterative: no RecursionError on deep files."""
    if root is None:
        return
    size: dict[int, int] = {}      # id(node) -> values it stands for, expanded
    on_path: set[int] = set()
    stack = [(root, False)]
    while stack:
        node, leaving = stack.pop()
        key = id(node)
        if leaving:
            on_path.discard(key)
            size[key] = 1 + sum(size[id(c)] for c in _children(node))
            if size[key] > MAX_EXPANDED_VALUES:
                raise AliasError(
                    f"the aliases here expand to more than {MAX_EXPANDED_VALUES:,} values; a "
                    f"case file is not meant to (a nesting of aliases?)",
                    node.start_mark.line + 1)
            continue
        if key in size:
            continue
        on_path.add(key)
        stack.append((node, True))
        if isinstance(node, yaml.MappingNode):
            seen: dict[str, int] = {}
            for k, _ in node.value:
                name = getattr(k, "value", None)
                if isinstance(name, str):
                    if name in seen:
                        raise DuplicateKeyError(
                            f"duplicate key '{name}' (line {k.start_mark.line + 1}; first given "
                            f"on line {seen[name]})",
                            k.start_mark.line + 1)
                    seen[name] = k.start_mark.line + 1
        for child in reversed(_children(node)):
            if id(child) in on_path:
                raise AliasError(
                    "an anchor (&name) that contains an alias of itself (*name): a recursive "
                    "structure, which a case cannot be", child.start_mark.line + 1)
            if id(child) not in size:
                stack.append((child, False))


def walk_yaml(node, data, loc, name_missing: bool = True) -> tuple[list[str], int | None]:
    """Follow ``loc`` through the YAML nodes and the loaded data.

    Returns the printable path (keys and list indices that exist, plus a final missing key) and the
    1-based line of the deepest node reached (the key's line for mapping entries)."""
    path: list[str] = []
    line = node.start_mark.line + 1 if node is not None else None
    for n, part in enumerate(loc):
        last = n == len(loc) - 1
        if isinstance(data, dict) and isinstance(part, str) and part in data:
            data = data[part]
            path.append(part)
            if isinstance(node, yaml.MappingNode):
                for k, v in node.value:
                    if getattr(k, "value", None) == part:
                        line, node = k.start_mark.line + 1, v
                        break
        elif isinstance(data, list) and isinstance(part, int) and 0 <= part < len(data):
            data = data[part]
            path.append(f"[{part}]")
            if isinstance(node, yaml.SequenceNode) and part < len(node.value):
                node = node.value[part]
                line = node.start_mark.line + 1
        elif last and name_missing and isinstance(data, dict) and isinstance(part, str) \
                and part.isidentifier():
            path.append(part)  # a missing (or unknown) key: name it, point at its parent
        # anything else is a union tag inserted by pydantic: skip it
    return path, line


def _models_in(tp) -> list[type[BaseModel]]:
    if isinstance(tp, type) and issubclass(tp, BaseModel):
        return [tp]
    out: list[type[BaseModel]] = []
    if typing.get_origin(tp) is not None or isinstance(tp, types.UnionType):
        for arg in typing.get_args(tp):
            out += _models_in(arg)
    return out


def field_description(model: type[BaseModel], loc) -> str | None:
    """Description (with the unit) of the field at a pydantic location, if any."""
    current: Any = model
    desc = None
    for part in loc:
        if not isinstance(part, str):
            continue
        for m in _models_in(current):
            if part in m.model_fields:
                info = m.model_fields[part]
                desc, current = info.description, info.annotation
                break
    return desc


def join_field_path(path: list[str]) -> str:
    out = ""
    for p in path:
        out += p if p.startswith("[") else (f".{p}" if out else p)
    return out or "<case>"


def format_errors(
    err: ValidationError,
    model: type[BaseModel],
    data: Any = None,
    node=None,
    source: str | None = None,
) -> str:
    """One line per problem: ``source:line: field.path: message``; messages for the same field
    (one per union member) are joined with 'or'."""
    merged: dict[tuple[str, int | None], list[str]] = {}
    for e in err.errors():
        loc = tuple(e["loc"])
        # a last part that is not a key of the file is a missing / unknown key, or else a
        # union tag of a model-level check (loading.shake): dropped then
        path, line = walk_yaml(node, data, loc, e["type"] in ("missing", "extra_forbidden")) \
            if data is not None else ([str(p) for p in loc], None)
        msg = e["msg"].removeprefix("Value error, ")
        if e["type"] in _NUMBER_ERRORS and isinstance(e.get("input"), str):
            desc = field_description(model, loc)
            msg += f" (got {e['input']!r}; give a plain number without a unit"
            msg += f": {desc})" if desc else ")"
        elif e["type"] == "extra_forbidden":
            msg = "unknown key (not part of the case schema; check the spelling)"
        elif e["type"] == "missing":
            desc = field_description(model, loc)
            msg = "missing required field" + (f" ({desc})" if desc else "")
        if not loc and data is not None:
            # a model-level check names its field at the head of the message ("imperfections.
            # bed_unevenness: ..."): point at that field's line, not the file's first
            head, sep, rest = msg.partition(": ")
            parts = head.split(".")
            if sep and all(p.isidentifier() for p in parts) and parts[0] in data:
                path, line = walk_yaml(node, data, tuple(parts))
                msg = rest
        key = (join_field_path(path), line)
        if msg not in merged.setdefault(key, []):
            merged[key].append(msg)
    lines = []
    for (path, line), msgs in merged.items():
        where = f"{source}:{line}: " if source and line else (f"line {line}: " if line else "")
        where = where if where else (f"{source}: " if source else "")
        lines.append(f"{where}{path}: {' or '.join(msgs)}")
    return "\n".join(lines)
