"""Count the engine's branches on "device or not" and on "one scene or several".

    python benchmarks/engine_branches.py [FILE ...]     # default: the engine's driver files

A branch is an ``if`` / ``elif`` / ternary / ``while`` whose test names the device
(``on_device``, ``device_arrays``, ``self._dev``, ``"cuda"``) or the number of scenes
(``.batched``, ``lone``, ``G == 1``, ``G > 1``, ``n_scenes == 1``); a flag handed on as an argument
(``patches_over_caps(..., batched)``) is not a branch.  Each one is printed with its place, then
the totals.  A text match on the source (ast), so a rename that hides a branch from it is
possible: read the list, not only the totals (benchmarks/RESULTS.md, "The engine by job").
"""

from __future__ import annotations

import ast
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DEFAULT = ("dem/engine/simulation.py", "dem/engine/assembly.py", "dem/engine/launcher.py",
           "dem/engine/residency.py", "dem/engine/stepsize.py")
DEVICE = re.compile(r"on_device|device_arrays|self\._dev\b|\"cuda\"")
SCENES = re.compile(r"\.batched\b(?!\))|\bnot self\.batched|\blone\b"
                    r"|\bG\s*[=><!]=?\s*1\b|n_scenes\s*[=><!]=?\s*1\b")


def branches(path: Path) -> list[tuple[str, int, str]]:
    """(kind, line, test) of each branch of ``path`` (module docstring)."""
    src = path.read_text()
    out = []
    for node in ast.walk(ast.parse(src)):
        if isinstance(node, (ast.If, ast.IfExp, ast.While)):
            test = ast.get_source_segment(src, node.test) or ""
            if re.search(r"patches_over_caps\(", test):
                continue
            for kind, rx in (("device", DEVICE), ("scenes", SCENES)):
                if rx.search(test):
                    out.append((kind, node.lineno, test))
    return out


def main(files: list[str]) -> None:
    totals = {"device": 0, "scenes": 0}
    for name in files or DEFAULT:
        path = Path(name) if Path(name).is_absolute() else ROOT / name
        if not path.exists():
            continue
        for kind, line, test in branches(path):
            totals[kind] += 1
            print(f"{kind:7s} {name}:{line}: {test[:90]}")
    print(f"device or not: {totals['device']}, one scene or several: {totals['scenes']}")


if __name__ == "__main__":
    main(sys.argv[1:])
