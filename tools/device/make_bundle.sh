#!/usr/bin/env bash
# Build .device/ (git-ignored) for a borrowed machine that has Python 3.12, numpy, scipy,
# matplotlib, pyyaml, rich but no taichi, pydantic, dask or pyvista (the device loans of this
# workplace, 2026-11): one zip of the missing pure packages and Taichi's wheel without its C API
# library and examples (38 MB: the tree that travels is capped at 64 MiB), the pyvista / VTK
# stand-ins of stubs/ and run_points.sh.  Run from the repository root; needs pip and the network.
set -euo pipefail
cd "$(git rev-parse --show-toplevel)"
grep -qx '/.device/' .git/info/exclude || echo '/.device/' >> .git/info/exclude
mkdir -p .device /tmp/device-wheels
python3 -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \
    --platform manylinux_2_28_x86_64 --platform manylinux_2_27_x86_64 \
    --platform manylinux_2_17_x86_64 --platform manylinux2014_x86_64 -d /tmp/device-wheels \
    "taichi==$(.venv/bin/pip show taichi | sed -n 's/^Version: //p')" \
    "pydantic==$(.venv/bin/python -c 'import pydantic; print(pydantic.VERSION)')" \
    "pydantic_core==$(.venv/bin/python -c 'import pydantic_core; print(pydantic_core.__version__)')" \
    annotated-types typing-inspection dill
python3 - <<'PY'
import glob, zipfile
with zipfile.ZipFile(".device/site.zip", "w", zipfile.ZIP_DEFLATED) as out:
    for whl in sorted(glob.glob("/tmp/device-wheels/*.whl")):
        z = zipfile.ZipFile(whl)
        for i in z.infolist():
            n = i.filename
            if n.startswith(("taichi/_lib/c_api", "taichi/examples")) or ".data/" in n:
                continue
            out.writestr(i, z.read(n), compress_type=zipfile.ZIP_DEFLATED, compresslevel=6)
PY
rm -rf .device/stubs && cp -r tools/device/stubs .device/ && cp tools/device/run_points.sh .device/
du -sh .device
