"""The README and the manual in docs/ name only things that exist.

A reader follows what the docs name: a file or folder of the repository, a Python module (or a
name in one), a ``dem`` command, a study of ``python -m studies``.  When code moves and the docs
stay, the reader is sent nowhere; these tests fail instead, naming the page and the reference.
What is checked, in README.md and docs/*.md:

* every path under one of the repository's top folders (``dem/``, ``postprocess/``, ``tests/``,
  ``cases/`` ...), in text, code or a link, and every relative link target: it exists (a
  ``path: name`` or ``path::test`` reference also names something in that file);
* every backticked dotted name under ``dem.``, ``dem_cli.``, ``postprocess.``, ``studies.``: a
  module, or a name defined in one (the module is found as a file; nothing is imported);
* every ``dem COMMAND`` and ``python -m studies STUDY``: a command of dem_cli/app.py, a study of
  studies/__main__.py.

Files a run writes (``summary.json``, ``runs/...``) are not in the repository; the few paths of
the docs that name such an output under a repository folder are allowed by name in
:data:`RUN_OUTPUTS`, each with its reason.  And docs/case-reference.md must be what
tools/case_reference.py makes from the schema now.
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
TOP = ("dem", "dem_cli", "postprocess", "studies", "tests", "docs", "cases", "results",
       "benchmarks", "tools", ".ci")

# paths under a repository folder that name what a run or a study writes, not a committed file
RUN_OUTPUTS = {
    "results/prediction/runs/DRAIN": "the drain file a user touches to end a prediction session",
    "results/imperfections/cases/<case>.yaml": "a placeholder for any of that folder's cases",
}

PATH_RE = re.compile(r"(?<![\w./-])((?:%s)/[\w./<>*{},+-]*)" % "|".join(re.escape(t) for t in TOP))
LINK_RE = re.compile(r"\]\(([^)#\s]+)(?:#[^)]*)?\)")
MODULE_RE = re.compile(r"`((?:dem|dem_cli|postprocess|studies)(?:\.[A-Za-z_]\w*)+)")
REF_RE = re.compile(r"`((?:%s)/[\w./-]+\.py)(?::\s*|::)([A-Za-z_][\w.]*)" %
                    "|".join(re.escape(t) for t in TOP))
DEM_RE = re.compile(r"`(?:[\w./]*/)?dem ([a-z][\w-]*)")
STUDY_RE = re.compile(r"python -m studies ([a-z][\w-]*)")


def _text(page: Path) -> str:
    return page.read_text()


def _clean(path: str) -> str:
    return path.rstrip(".,;:)`'\"")


def _defined(source: str, name: str) -> bool:
    """Whether ``name`` is defined in a module's source: a def, a class, an assignment or an
    import of that name."""
    if re.search(rf"^\s*(?:async\s+)?(?:def|class)\s+{re.escape(name)}\b"
                 rf"|^\s*{re.escape(name)}\s*[:=]|^\s*(?:from\s+\S+\s+)?import\b.*\b{re.escape(name)}\b",
                 source, re.M):
        return True
    # a name imported in a parenthesised, multi-line ``from x import (...)``
    return any(re.search(rf"\b{re.escape(name)}\b", block)
               for block in re.findall(r"^from\s+\S+\s+import\s+\(([^)]*)\)", source, re.M))


def _module_file(parts: list[str]) -> tuple[Path | None, list[str]]:
    """The longest prefix of a dotted name that is a module file, and the rest."""
    for k in range(len(parts), 0, -1):
        base = ROOT.joinpath(*parts[:k])
        for candidate in (base.with_suffix(".py"), base / "__init__.py"):
            if candidate.is_file():
                return candidate, parts[k:]
    return None, parts


def _paths(page: Path) -> list[str]:
    text = _text(page)
    found = [_clean(m) for m in PATH_RE.findall(text)]
    for target in LINK_RE.findall(text):
        if "://" in target:
            continue
        resolved = (page.parent / target).resolve()
        try:
            found.append(resolved.relative_to(ROOT).as_posix())
        except ValueError:
            found.append(target)  # a link out of the repository: reported as missing
    return sorted(set(p for p in found if p))


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.relative_to(ROOT).as_posix())
def test_every_named_path_exists(page):
    missing = []
    for path in _paths(page):
        if path in RUN_OUTPUTS:
            continue
        if any(c in path for c in "<>*{}"):  # a pattern (results/*/README.md), not one path
            continue
        if not (ROOT / path).exists():
            missing.append(path)
    assert not missing, f"{page.name} names paths that do not exist: {missing}"


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.relative_to(ROOT).as_posix())
def test_every_named_module_and_name_exists(page):
    text = _text(page)
    missing = []
    for dotted in sorted(set(MODULE_RE.findall(text))):
        path, rest = _module_file(dotted.split("."))
        if path is None:
            missing.append(dotted)
        elif rest and not _defined(path.read_text(), rest[0]):
            missing.append(dotted)
    for path, name in sorted(set(REF_RE.findall(text))):
        file = ROOT / path
        if file.is_file() and not _defined(file.read_text(), name.split(".")[0]):
            missing.append(f"{path}: {name}")
    assert not missing, f"{page.name} names modules or names that do not exist: {missing}"


def _dem_commands() -> set[str]:
    source = (ROOT / "dem_cli" / "app.py").read_text()
    return set(re.findall(r"@app\.command\(\)\s*\ndef (\w+)\(", source))


def _studies() -> set[str]:
    source = (ROOT / "studies" / "__main__.py").read_text()
    block = source[source.index("STUDIES = {"):]
    return set(re.findall(r'^\s*"([\w-]+)": \(', block, re.M))


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.relative_to(ROOT).as_posix())
def test_every_named_command_and_study_exists(page):
    text = _text(page)
    commands, studies = _dem_commands(), _studies()
    assert {"run", "check", "sweep"} <= commands  # the parser itself works
    assert {"tilt", "shake", "prediction"} <= studies
    bad = sorted({c for c in DEM_RE.findall(text) if c not in commands}
                 | {f"studies {s}" for s in STUDY_RE.findall(text)
                    if s not in studies and s not in ("--help",)})
    assert not bad, f"{page.name} names commands or studies that do not exist: {bad}"


def test_the_checks_catch_a_missing_path_module_and_command(tmp_path, monkeypatch):
    """The parsers find what they must: a page naming a missing file, module and command fails
    every check (so that the tests above cannot pass by finding nothing)."""
    page = tmp_path / "page.md"
    page.write_text("See `dem/no_such_module.py`, `dem.engine.no_such_name`, `dem frobnicate`, "
                    "`python -m studies no-such-study` and [x](../docs/nothing.md).\n")
    monkeypatch.setattr(sys.modules[__name__], "_text", lambda p: page.read_text())
    for test in (test_every_named_path_exists, test_every_named_module_and_name_exists,
                 test_every_named_command_and_study_exists):
        with pytest.raises(AssertionError):
            test(ROOT / "docs" / "page.md")


def test_case_reference_is_what_the_schema_gives():
    """docs/case-reference.md is generated from the case schema; a schema change (a new field,
    a new default, a new description) must regenerate it."""
    done = subprocess.run([sys.executable, str(ROOT / "tools" / "case_reference.py"), "--check"],
                          cwd=ROOT, capture_output=True, text=True,
                          env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"})
    assert done.returncode == 0, (
        "docs/case-reference.md differs from the schema: regenerate it with "
        "`python tools/case_reference.py` and commit it\n" + done.stderr)
