"""The kernels' warm-up (tests/warm_kernels.py, run by tests/conftest.py before the workers):
each variant's case asks for what the variant names, and the stamp makes it a no-op only while
it matches the current kernels' sources and settings."""

import json
import os

import pytest

from tests import warm_kernels as wk


@pytest.mark.parametrize("v", wk.VARIANTS, ids=wk.describe)
def test_each_variant_case_asks_for_what_the_variant_names(v):
    case = wk.case_of(v)
    assert case.solver.mode == v["mode"]
    assert case.material.normal_law == v.get("law", "linear")
    assert case.material.normal_damping == v.get("damping", "critical")
    assert (case.solver.overlap_reuse > 0) == bool(v.get("overlap"))
    assert (case.imperfections.bed_unevenness > 0) == bool(v.get("imperfect"))


def test_the_stamp_skips_the_warm_up_only_for_the_current_kernels(tmp_path, monkeypatch):
    monkeypatch.setenv("TI_OFFLINE_CACHE_FILE_PATH", str(tmp_path))
    monkeypatch.delenv("TI_OFFLINE_CACHE", raising=False)
    assert wk.needed()                                   # an empty cache
    stamp = tmp_path / wk.STAMP
    stamp.write_text(json.dumps({"fingerprint": wk.fingerprint()}))
    assert not wk.needed()                               # the current kernels
    monkeypatch.setenv("TI_DEBUG", "1")                  # a Taichi setting changes the kernels
    assert wk.needed()
    monkeypatch.delenv("TI_DEBUG")
    threads = int(os.environ.get("DEM_THREADS") or 1)
    monkeypatch.setenv("DEM_THREADS", str(threads + 1))  # the thread count: in the cache key
    assert wk.needed()
    stamp.write_text("not json")
    assert wk.needed()
    monkeypatch.setenv("TI_OFFLINE_CACHE", "0")          # no cache: nothing to warm
    assert not wk.needed()


def test_an_ended_subprocess_is_reaped_with_its_exit_code_and_cpu_time():
    """The warm-up's account of each variant: the exit code, and the CPU seconds the kernel
    charged to the child (a busy loop of 0.3 CPU-s reads at least that, less the clock's tick)."""
    import subprocess
    import sys
    import time

    burn = ("import sys, time\nt = time.process_time()\n"
            "while time.process_time() - t < 0.3: pass\nsys.exit(3)")
    p = subprocess.Popen([sys.executable, "-c", burn])
    t0 = time.monotonic()
    while (cpu := wk.reap(p)) is None:
        assert time.monotonic() - t0 < 60
        time.sleep(0.05)
    assert p.returncode == 3
    assert cpu >= 0.3 - 0.02


@pytest.mark.parametrize("parts", [1, 2, 3, 4, 64])
def test_the_lanes_share_out_every_variant_once_in_about_equal_parts(parts):
    """Each variant in exactly one lane, at most ``parts`` lanes, each in the order of
    VARIANTS; the largest greedy (longest first) share exceeds the mean by less than the
    largest single variant (the bound of the greedy list schedule)."""
    assert len(wk.COMPILE_CPU_S) == len(wk.VARIANTS)
    got = wk.lanes(parts)
    assert sorted(k for lane in got for k in lane) == list(range(len(wk.VARIANTS)))
    assert len(got) == min(parts, len(wk.VARIANTS)) and all(lane == sorted(lane) for lane in got)
    loads = [sum(wk.COMPILE_CPU_S[k] for k in lane) for lane in got]
    assert max(loads) < sum(loads) / len(loads) + max(wk.COMPILE_CPU_S)
