"""Do two versions of the code give the same output files?  (A refactor must not change
results.)

    python benchmarks/same_outputs.py record DIR     # run the cases below into DIR
    python benchmarks/same_outputs.py compare A B    # compare two such directories file by file

The runs (through the command line, as a user runs them; ~4 min on the 2-core VM):
  * tilt   ``dem run`` of the in-plane 5 x 5 small-brick wall (collapse, mechanism, limit analysis)
           and ``dem run`` of the block on the tilting table;
  * shake  ``dem run`` of the shaken block (frames, VTK) and of Model II, group 3, cut to one
           cycle of 2.8 Hz in 0.4 s (instruments.npz), then ``dem post`` of the Model II run (the shake analysis);
  * warped ``dem run`` of the imperfect wall at rest with the overlap reuse on, cut to 0.2 s
           (the warped kernels' narrow phase and coherence.warped_faces);
  * hyperbolic ``dem run`` of the column on the hyperbolic joint law, cut to 0.2 s (the
           hyperbolic kernels and the closure-limit check);
  * sweep  ``dem sweep`` of the shaken block at two frequencies, two cycles each, one worker:
           point by point, and with ``--batch 2`` (both points as scenes of one engine).
Every file is compared: JSON after dropping the keys that hold timings or machine facts
(``TIMING_KEYS``) or the path of the checkout (``PATH_KEYS``), ``.npz`` array by array (exactly), every other file byte for byte.
Exit status 0 when everything matches, 1 otherwise (the differences are printed).
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
DEM = [sys.executable, "-m", "dem_cli"]
TIMING_KEYS = {"wall_seconds", "compile_seconds", "brick_steps_per_second", "cpu_seconds",
               "wall_s", "elapsed_s", "started", "finished", "host", "seconds", "run_seconds",
               "date", "created", "python", "version", "integration_seconds",
               "engine_seconds"}
# keys that hold a path of the tree the runs were recorded from (two checkouts differ there)
PATH_KEYS = {"source"}


def _cut_case(src: Path, dst: Path, duration: float, cycles: int | None = None) -> Path:
    """``src`` with run.duration ``duration`` (s) and, for a shake, loading.cycles ``cycles``
    (a run must not end before its shake does: dem.validate)."""
    case = yaml.safe_load(src.read_text())
    case["run"]["duration"] = duration
    if cycles is not None:
        case["loading"]["cycles"] = cycles
    dst.write_text(yaml.safe_dump(case))
    return dst


def record(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    model_ii = _cut_case(ROOT / "cases/shake/model-ii/group-3-y-1.53.yaml",
                         out / "model-ii-cut.yaml", 0.4, cycles=1)
    imperfect = _cut_case(ROOT / "cases/analytic/imperfect-wall-overlap-reuse.yaml",
                          out / "imperfect-wall-cut.yaml", 0.2)
    hyperbolic = _cut_case(ROOT / "cases/joint/hyperbolic-column.yaml",
                           out / "hyperbolic-column-cut.yaml", 0.2)
    block = ROOT / "cases/analytic/block-under-base-acceleration.yaml"
    commands = [
        DEM + ["run", str(ROOT / "cases/tilt/in-plane/small-5x5.yaml"), "--out",
               str(out / "tilt-wall"), "--no-progress"],
        DEM + ["run", str(ROOT / "cases/analytic/block-on-tilt.yaml"), "--out",
               str(out / "tilt-block"), "--no-progress"],
        DEM + ["run", str(block), "--out", str(out / "shake-block"), "--no-progress"],
        DEM + ["run", str(model_ii), "--out", str(out / "shake-model-ii"), "--no-progress"],
        DEM + ["post", str(out / "shake-model-ii")],
        DEM + ["run", str(imperfect), "--out", str(out / "warped-wall"), "--no-progress"],
        DEM + ["run", str(hyperbolic), "--out", str(out / "hyperbolic-column"),
               "--no-progress"],
        DEM + ["sweep", str(block), "--out", str(out / "sweep-block"), "--frequencies",
               "1.5,2.0", "--cycles", "2", "--workers", "1"],
        DEM + ["sweep", str(block), "--out", str(out / "sweep-block-batched"), "--frequencies",
               "1.5,2.0", "--cycles", "2", "--workers", "1", "--batch", "2"],
    ]
    for cmd in commands:
        print("$", " ".join(cmd[2:]), flush=True)
        proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
        (out / "log.txt").open("a").write(f"$ {' '.join(cmd[2:])}\nexit {proc.returncode}\n"
                                          f"{proc.stdout}\n{proc.stderr}\n")
        print(f"  exit {proc.returncode}", flush=True)
        if proc.returncode != 0:
            print(proc.stderr[-2000:], flush=True)


def _strip(obj):
    if isinstance(obj, dict):
        return {k: _strip(v) for k, v in obj.items()
                if k not in TIMING_KEYS and k not in PATH_KEYS}
    if isinstance(obj, list):
        return [_strip(v) for v in obj]
    return obj


def _diff_json(a, b, path="") -> list[str]:
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for k in sorted(set(a) | set(b)):
            if k not in a or k not in b:
                out.append(f"{path}/{k}: only in {'B' if k not in a else 'A'}")
            else:
                out += _diff_json(a[k], b[k], f"{path}/{k}")
        return out
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        return [d for i, (x, y) in enumerate(zip(a, b)) for d in _diff_json(x, y, f"{path}[{i}]")]
    return [] if a == b else [f"{path}: {str(a)[:80]} != {str(b)[:80]}"]


def compare_file(a: Path, b: Path) -> list[str]:
    if a.suffix == ".json":
        return _diff_json(_strip(json.loads(a.read_text())), _strip(json.loads(b.read_text())))
    if a.suffix == ".npz":
        out = []
        with np.load(a) as fa, np.load(b) as fb:
            for k in sorted(set(fa.files) | set(fb.files)):
                if k not in fa.files or k not in fb.files:
                    out.append(f"{k}: only in one")
                elif fa[k].shape != fb[k].shape or not np.array_equal(fa[k], fb[k]):
                    out.append(f"{k}: arrays differ")
        return out
    if a.name == "log.txt":
        return []
    return [] if a.read_bytes() == b.read_bytes() else ["bytes differ"]


def compare(a_dir: Path, b_dir: Path) -> int:
    files_a = {p.relative_to(a_dir) for p in a_dir.rglob("*") if p.is_file()}
    files_b = {p.relative_to(b_dir) for p in b_dir.rglob("*") if p.is_file()}
    bad = 0
    for rel in sorted(files_a ^ files_b):
        print(f"{rel}: only in {'A' if rel in files_a else 'B'}")
        bad += 1
    same = 0
    for rel in sorted(files_a & files_b):
        diffs = compare_file(a_dir / rel, b_dir / rel)
        if diffs:
            bad += 1
            print(f"{rel}: " + "; ".join(diffs[:6]) + (" ..." if len(diffs) > 6 else ""))
        else:
            same += 1
    print(f"{same} files identical, {bad} differ or are missing")
    return 1 if bad else 0


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "record":
        record(Path(sys.argv[2]))
    elif len(sys.argv) == 4 and sys.argv[1] == "compare":
        sys.exit(compare(Path(sys.argv[2]), Path(sys.argv[3])))
    else:
        sys.exit(__doc__)
