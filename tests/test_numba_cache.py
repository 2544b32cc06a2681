"""The package's one numba cache locator (pyfmu_wrapper/_jit.py), as the FMUs use it through their
bundled loader (pyfmu_wrapper/fmi/fmu_loader.py): compiled once, then loaded from the cache by a
fresh process from another extraction folder; keyed by the bundle (a modified bundle is refused,
never run with another bundle's cache)."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
import zipfile

from _fmu_support import built_fmus

RUN = textwrap.dedent("""
    import sys, fmpy
    r = fmpy.simulate_fmu(sys.argv[1], stop_time=0.01, output_interval=1e-3,
                          start_values={"inerter": 2, "eps": 1e-4, "ki": 2e7, "y0": 0.001})
    print("y_end", repr(float(r["y"][-1])))
""")


def _run(fmu, cache, cwd, debug=False):
    env = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_")}
    env["PYFMU_CACHE_DIR"] = str(cache)
    if debug:
        env["NUMBA_DEBUG_CACHE"] = "1"
    return subprocess.run(
        [sys.executable, "-c", RUN, str(fmu)], capture_output=True, text=True, cwd=cwd, env=env, timeout=900
    )


def test_fmu_compiles_once_then_loads_from_its_bundle_cache(tmp_path):
    fmu = built_fmus()["TMDInerter"]
    with zipfile.ZipFile(fmu) as z:
        package = next(n.split("/")[1] for n in z.namelist() if n.startswith("resources/_pyfmu_"))
    cache = tmp_path / "cache"
    first = _run(fmu, cache, tmp_path, debug=True)
    assert first.returncode == 0, first.stderr[-3000:]
    saved = [line for line in first.stdout.splitlines() if "data saved to" in line and package in line]
    assert saved, first.stdout[-2000:]  # compiled, and cached under <cache>/<package>/
    assert (cache / package / "solvers").is_dir() and (cache / package / "fmi").is_dir()
    # a fresh process, another extraction folder (fmpy extracts anew): everything from the cache
    second = _run(fmu, cache, tmp_path, debug=True)
    assert second.returncode == 0, second.stderr[-3000:]
    assert not [line for line in second.stdout.splitlines() if "data saved to" in line and package in line]
    assert [line for line in second.stdout.splitlines() if "data loaded from" in line and package in line]
    # and the same numbers
    assert first.stdout.splitlines()[-1] == second.stdout.splitlines()[-1]


def test_modified_bundle_is_refused_not_run_with_the_cache(tmp_path):
    fmu = built_fmus()["TMDInerter"]
    bad = tmp_path / "TMDInerter.fmu"
    with zipfile.ZipFile(fmu) as src, zipfile.ZipFile(bad, "w") as dst:
        for item in src.infolist():
            data = src.read(item.filename)
            if item.filename.endswith("/physics/kernels.py"):
                data += b"\n# changed after the build\n"
            dst.writestr(item, data)
    r = _run(bad, tmp_path / "cache", tmp_path)
    assert r.returncode != 0
    assert "was modified after the build" in (r.stdout + r.stderr)
