"""The package's layers point one way (issue 16, docs/architecture.md): every module imports only
modules of its own layer or of layers below it.  Read from the source (ast), so a lazy import
inside a function counts as much as one at the top."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

# lowest first; a module belongs to the first entry whose prefix matches its dotted name
LAYERS = [
    ("base", ("dem.quaternion", "dem.output.atomic", "dem.signals", "dem.ti_runtime",
              "dem.case_errors", "dem.rundir", "dem.collapse", "dem.units")),
    ("scene", ("dem.scene",)),
    ("builders", ("dem.builders", "dem.imperfections")),
    ("case schema", ("dem.case",)),
    ("loads, instruments, outputs", ("dem.loading", "dem.table_motion", "dem.instruments",
                                     "dem.compliance",
                                     "dem.output")),
    ("engine", ("dem.engine",)),
    ("run loop", ("dem.run", "dem.batch", "dem.validate", "dem.rocking")),
    ("analysis", ("postprocess",)),
    ("commands and studies", ("dem.commands", "dem.cli", "studies", "postprocess.tilt_study",
                              "postprocess.shake_study", "postprocess.calibration_study",
                              "postprocess.qs_validation",
                              "postprocess.prediction_study",
                              "postprocess.chapter3_check",
                              "postprocess.unevenness_sensitivity",
                              "postprocess.resonance_search",
                              "postprocess.point_pool",
                              "postprocess.rocking_report",
                              "postprocess.rocking_vs_dem_sweep")),
]


def _layer(name: str) -> int | None:
    best, best_len = None, -1
    for i, (_, prefixes) in enumerate(LAYERS):
        for p in prefixes:
            if (name == p or name.startswith(p + ".")) and len(p) > best_len:
                best, best_len = i, len(p)
    return best


def _modules():
    for pkg in ("dem", "postprocess", "studies"):
        for path in sorted((ROOT / pkg).rglob("*.py")) if (ROOT / pkg).is_dir() else []:
            rel = path.relative_to(ROOT).with_suffix("")
            parts = list(rel.parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            yield ".".join(parts), path


def _imports(name: str, path: Path) -> set[str]:
    tree = ast.parse(path.read_text())
    pkg = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = pkg.split(".")
                base = base[: len(base) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            subs = {f"{mod}.{a.name}" for a in node.names}  # `from dem import quaternion`
            named = subs & MODULE_NAMES
            out.update(named)
            if named != subs:  # names defined in ``mod`` itself (not only its submodules)
                out.add(mod)
    return {m for m in out if m.split(".")[0] in ("dem", "postprocess", "studies")}


MODULES = dict(_modules())
MODULE_NAMES = set(MODULES)


def test_every_module_has_a_layer():
    missing = [m for m in MODULES if m not in ("dem", "postprocess", "studies")
               and _layer(m) is None]
    assert not missing, f"modules without a layer in tests/test_layers.py: {missing}"


@pytest.mark.parametrize("name", sorted(MODULES))
def test_imports_point_down(name):
    mine = _layer(name)
    if mine is None:
        return  # the package roots (dem/__init__.py: version and environment only)
    up = []
    for target in sorted(_imports(name, MODULES[name])):
        theirs = _layer(target)
        if theirs is not None and theirs > mine:
            up.append(f"{target} ({LAYERS[theirs][0]})")
    assert not up, f"{name} ({LAYERS[mine][0]}) imports a layer above it: {up}"


def test_no_two_modules_import_each_other():
    """No mutual imports (postprocess/shake.py <-> excited.py was one), lazy ones included."""
    deps = {m: {t for t in _imports(m, p) if t in MODULES and t != m} for m, p in MODULES.items()}
    pairs = sorted({tuple(sorted((a, b))) for a, ts in deps.items() for b in ts
                    if a in deps.get(b, set())})
    assert not pairs, f"modules importing each other: {pairs}"
