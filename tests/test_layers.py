"""The packages' layers point one way (docs/architecture.md): dem_cli (the command line) ->
postprocess (the analysis) -> dem (the simulator), with the studies above all; every module
imports only modules of its own layer or of layers below it, no two modules import each other,
and no module reaches for another module's private name.  Read from the source (ast), so a lazy
import inside a function counts as much as one at the top.

A module's layer is its folder's (:data:`FOLDERS`): a new study under studies/, a new analysis
under postprocess/ or a new piece of the engine under dem/engine/ has its layer without an edit
here.  Only the loose modules directly in dem/ are named one by one (:data:`LOOSE`)."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: the packages, lowest first: each imports only itself and those before it
PACKAGES = ("dem", "postprocess", "dem_cli", "studies")

#: the layers, lowest first
LAYERS = ("base", "scene", "builders", "case schema", "loads, instruments, outputs", "engine",
          "run loop", "analysis", "commands", "studies")

#: folder -> layer; a module takes the layer of the deepest folder that holds it
FOLDERS = {
    "dem/builders": "builders",
    "dem/case": "case schema",
    "dem/output": "loads, instruments, outputs",
    "dem/engine": "engine",
    "dem/run": "run loop",
    "dem/rocking": "run loop",
    "postprocess": "analysis",
    # the one place that joins dem and postprocess: the `dem` command line and its bodies
    "dem_cli": "commands",
    # a study drives many runs through the commands' bodies (dem_cli.commands.sweep.run_sweep)
    "studies": "studies",
}

#: the modules directly in dem/ (no folder of their own), by name
LOOSE = {
    "dem.quaternion": "base", "dem.signals": "base", "dem.ti_runtime": "base",
    "dem.ti_import": "base", "dem.environment": "base",
    "dem.case_errors": "base", "dem.rundir": "base", "dem.collapse": "base", "dem.units": "base",
    # the sine of both models (numpy only): the case schema builds it (dem.case.loadings)
    "dem.table_motion": "base",
    "dem.scene": "scene",
    "dem.imperfections": "builders",
    "dem.loading": "loads, instruments, outputs",
    "dem.instruments": "loads, instruments, outputs", "dem.compliance": "loads, instruments, outputs",
    "dem.batch": "run loop", "dem.validate": "run loop",
}
#: dem/output/atomic.py is below its folder: everything writes files atomically
EXCEPTIONS = {"dem.output.atomic": "base"}


def layer_of(name: str, path: Path) -> int | None:
    """The layer (index into LAYERS) of module ``name`` at ``path``; None for a package root."""
    if name in EXCEPTIONS:
        return LAYERS.index(EXCEPTIONS[name])
    if name in LOOSE:
        return LAYERS.index(LOOSE[name])
    rel = path.relative_to(ROOT).parent
    for folder in [rel, *rel.parents]:
        if folder.as_posix() in FOLDERS:
            return LAYERS.index(FOLDERS[folder.as_posix()])
    return None


def _modules():
    for pkg in PACKAGES:
        for path in sorted((ROOT / pkg).rglob("*.py")) if (ROOT / pkg).is_dir() else []:
            rel = path.relative_to(ROOT).with_suffix("")
            parts = list(rel.parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            yield ".".join(parts), path


MODULES = dict(_modules())
MODULE_NAMES = set(MODULES)


def _resolve(name: str, path: Path, node: ast.ImportFrom) -> str:
    if not node.level:
        return node.module or ""
    pkg = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
    base = pkg.split(".")
    base = base[: len(base) - node.level + 1]
    return ".".join(base + ([node.module] if node.module else []))


def _imports(name: str, path: Path) -> set[str]:
    tree = ast.parse(path.read_text())
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            mod = _resolve(name, path, node)
            subs = {f"{mod}.{a.name}" for a in node.names}  # `from dem import quaternion`
            named = subs & MODULE_NAMES
            out.update(named)
            if named != subs:  # names defined in ``mod`` itself (not only its submodules)
                out.add(mod)
    return {m for m in out if m.split(".")[0] in PACKAGES}


def _private(attr: str) -> bool:
    return attr.startswith("_") and not (attr.startswith("__") and attr.endswith("__"))


def private_uses(name: str, path: Path) -> list[str]:
    """Where module ``name`` uses another module's private name: ``from x import _y``, or
    ``m._y`` with ``m`` a module it imported (``import x as m``, ``from pkg import m``).  Its own
    names, and dunders, are not private uses."""
    tree = ast.parse(path.read_text())
    aliases: dict[str, str] = {}
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                aliases[a.asname or a.name.split(".")[0]] = a.name if a.asname else \
                    a.name.split(".")[0]
        elif isinstance(node, ast.ImportFrom):
            mod = _resolve(name, path, node)
            for a in node.names:
                full = f"{mod}.{a.name}"
                if full in MODULE_NAMES or mod.split(".")[0] not in PACKAGES:
                    aliases[a.asname or a.name] = full
                if _private(a.name) and mod != name and full not in MODULE_NAMES:
                    found.append(f"line {node.lineno}: from {mod} import {a.name}")
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) \
                and node.value.id in aliases and _private(node.attr):
            target = aliases[node.value.id]
            if target != name and target.split(".")[0] in (*PACKAGES, "tests"):
                found.append(f"line {node.lineno}: {node.value.id}.{node.attr} ({target})")
    return found


def test_every_module_has_a_layer():
    missing = [m for m, p in MODULES.items() if m not in PACKAGES and layer_of(m, p) is None]
    assert not missing, (f"modules without a layer: {missing}; put them in a folder of FOLDERS "
                         f"(tests/test_layers.py) or, directly in dem/, name them in LOOSE")


def test_layers_come_from_folders_not_from_a_list_of_studies():
    """Every study module is in the top layer by its folder alone, and none is named anywhere in
    this file's tables."""
    studies = [m for m in MODULES if m.startswith("studies.")]
    assert studies, "no studies/ package"
    top = LAYERS.index("studies")
    assert all(layer_of(m, MODULES[m]) == top for m in studies)
    assert not [m for m in (*LOOSE, *EXCEPTIONS)
                if m.startswith(("studies", "postprocess", "dem_cli"))]
    assert all(layer_of(m, p) == LAYERS.index("analysis") for m, p in MODULES.items()
               if m.startswith("postprocess."))


@pytest.mark.parametrize("name", sorted(MODULES))
def test_imports_point_down(name):
    mine = layer_of(name, MODULES[name])
    if mine is None:
        return  # the package roots (dem/__init__.py: version and environment only)
    up = []
    for target in sorted(_imports(name, MODULES[name])):
        theirs = layer_of(target, MODULES[target]) if target in MODULES else None
        if theirs is not None and theirs > mine:
            up.append(f"{target} ({LAYERS[theirs]})")
    assert not up, f"{name} ({LAYERS[mine]}) imports a layer above it: {up}"


def upward_package_imports(name: str, path: Path) -> list[str]:
    """The imports of module ``name`` at ``path`` that reach a package after its own in
    :data:`PACKAGES` (dem importing postprocess or dem_cli, postprocess importing dem_cli ...)."""
    mine = PACKAGES.index(name.split(".")[0])
    return sorted(t for t in _imports(name, path) if PACKAGES.index(t.split(".")[0]) > mine)


@pytest.mark.parametrize("name", sorted(MODULES))
def test_packages_point_down(name):
    """dem imports neither postprocess nor dem_cli, and postprocess does not import dem_cli:
    checked by package, so the package roots (dem/__init__.py) and an import of a whole package
    (``import postprocess``), which have no layer of their own, count too."""
    up = upward_package_imports(name, MODULES[name])
    assert not up, f"{name} imports a package above its own: {up}"


def test_the_package_rule_catches_dem_importing_postprocess(tmp_path):
    """The rule itself, on a hand-made module of dem: a lazy import of postprocess inside a
    function, a whole-package import and an import of the command line are each caught; imports
    of dem itself and of libraries outside the project are not."""
    src = ("import numpy as np\n"
           "from dem.run import run_case\n"
           "import postprocess\n"
           "def f():\n    from postprocess.tilt import tilt_mechanism\n"
           "    from dem_cli.commands.exit_codes import ExitCode\n")
    path = tmp_path / "m.py"
    path.write_text(src)
    assert upward_package_imports("dem.fake", path) == [
        "dem_cli.commands.exit_codes", "postprocess", "postprocess.tilt"]


def test_no_two_modules_import_each_other():
    """No mutual imports (postprocess/shake.py <-> excited.py was one), lazy ones included."""
    deps = {m: {t for t in _imports(m, p) if t in MODULES and t != m} for m, p in MODULES.items()}
    pairs = sorted({tuple(sorted((a, b))) for a, ts in deps.items() for b in ts
                    if a in deps.get(b, set())})
    assert not pairs, f"modules importing each other: {pairs}"


@pytest.mark.parametrize("name", sorted(MODULES))
def test_no_module_uses_another_modules_private_names(name):
    found = private_uses(name, MODULES[name])
    assert not found, (f"{name} uses private names of other modules (make them public "
                       f"functions): {found}")


TEST_MODULES = {f"tests.{p.stem}": p for p in sorted((ROOT / "tests").glob("*.py"))}


@pytest.mark.parametrize("name", sorted(TEST_MODULES))
def test_no_test_module_uses_another_modules_private_names(name):
    """The tests too: a helper another test module needs, or an internal a test checks, has a
    public name in its module (private names of libraries outside the project, such as
    Taichi's, are not the rule's)."""
    found = private_uses(name, TEST_MODULES[name])
    assert not found, (f"{name} uses private names of other modules (make them public): "
                       f"{found}")


def test_the_private_name_rule_catches_both_forms(tmp_path):
    """The rule itself, on a hand-made module: both forms are caught, a module's own private
    names, dunders and a private name of a library outside the project are not."""
    src = ("from studies.prediction import plan as pl\n"
           "from postprocess.sweep import _x\n"
           "import numpy as np\n"
           "def _mine():\n    return 1\n"
           "y = pl._hidden + pl.__name__ + np._NoValue + _mine()\n")
    path = tmp_path / "m.py"
    path.write_text(src)
    found = private_uses("studies.fake", path)
    assert len(found) == 2 and "import _x" in found[0] and "pl._hidden" in found[1]


#: the one module that chooses matplotlib's backend (Agg: plots are files, never a window)
BACKEND_MODULE = "dem.output.plotting"


def backend_choices(path: Path) -> list[int]:
    """The lines of ``path`` that call ``matplotlib.use(...)``."""
    return [node.lineno for node in ast.walk(ast.parse(path.read_text()))
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
            and node.func.attr == "use" and isinstance(node.func.value, ast.Name)
            and node.func.value.id == "matplotlib"]


def test_matplotlib_backend_is_chosen_in_one_place():
    """Every plot gets pyplot from dem.output.plotting.agg_pyplot, so a headless worker never
    depends on which plot ran first; no other module (nor benchmark script) calls
    ``matplotlib.use``."""
    scripts = {f"benchmarks.{p.stem}": p for p in sorted((ROOT / "benchmarks").glob("*.py"))}
    elsewhere = {name: lines for name, path in {**MODULES, **scripts}.items()
                 if name != BACKEND_MODULE and (lines := backend_choices(path))}
    assert not elsewhere, f"use dem.output.plotting.agg_pyplot instead: {elsewhere}"
    assert backend_choices(MODULES[BACKEND_MODULE])  # the rule looks for the right call


def test_agg_pyplot_selects_agg():
    from dem.output.plotting import agg_pyplot

    plt = agg_pyplot()
    assert plt.get_backend().lower() == "agg"
