"""Compiled code follows the source: the numba cache cannot go stale.

numba validates a cached function against its own file only, so a cached function that calls a
kernel of another file used to keep the old kernel after an edit (doubling ``excitation`` left
``steady_state`` unchanged until ``__pycache__`` was deleted by hand). The package's ``njit``
keys the cache by the hash of the compiled layer (``pyfmu_wrapper/_jit.py``). These tests copy
the package to a temporary folder, run compiled code that calls a kernel of another file in a
fresh interpreter, edit the kernel, and run again: the new result appears with no manual step,
and an unchanged package loads from the cache.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import pyfmu_wrapper
from pyfmu_wrapper import codeversion

PKG = Path(pyfmu_wrapper.__file__).resolve().parent

PROBE = '''"""Test probe: a cached compiled function in one file calling a kernel of another."""
from .._jit import njit
from .kernels import excitation


@njit(cache=True)
def probe(t, p):
    return excitation(t, p)
'''

RUN = r"""
import numpy as np
import pyfmu_wrapper
from pyfmu_wrapper.physics._probe import probe
from pyfmu_wrapper.physics.params import BaseParams, TMDParams, pack
assert pyfmu_wrapper.__file__.startswith({root!r}), pyfmu_wrapper.__file__
v = probe(0.0, pack(BaseParams(), TMDParams(), 20.0))
print(repr(float(v)), probe.stats.cache_hits.get(probe.signatures[0], 0) if probe.signatures else 0)
"""


def _copy(tmp_path: Path) -> Path:
    dst = tmp_path / "src" / "pyfmu_wrapper"
    shutil.copytree(PKG, dst, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    (dst / "physics" / "_probe.py").write_text(PROBE)
    return dst


def _run(root: Path, extra: str = "") -> tuple[float, int]:
    env = dict(os.environ, PYTHONPATH=str(root.parent), NUMBA_CACHE_DIR="")
    env.pop("NUMBA_CACHE_DIR")
    code = RUN.format(root=str(root)) + extra
    out = subprocess.run(
        [sys.executable, "-c", code], cwd=root.parent, env=env, capture_output=True, text=True, timeout=300
    )
    assert out.returncode == 0, out.stderr[-3000:]
    value, hits = out.stdout.split()[-2:]
    return float(value), int(hits)


@pytest.mark.timeout(600)
def test_editing_a_kernel_in_another_file_recompiles_its_callers(tmp_path):
    root = _copy(tmp_path)
    v1, hits1 = _run(root)
    assert v1 == 200.0 and hits1 == 0  # F cos(0), compiled and written to the cache
    v2, hits2 = _run(root)
    assert v2 == 200.0 and hits2 == 1  # same sources: loaded from the cache
    k = root / "physics" / "kernels.py"
    src = k.read_text()
    assert src.count("return p[P_F] * _cos(p[P_W] * t)") == 1
    k.write_text(src.replace("return p[P_F] * _cos(p[P_W] * t)", "return 2.0 * p[P_F] * _cos(p[P_W] * t)"))
    v3, hits3 = _run(root)
    assert v3 == 400.0 and hits3 == 0  # the caller in _probe.py was recompiled against the new kernel
    assert any(p.name.startswith("numba-") for p in (root / "physics" / "__pycache__").iterdir())


def test_compiled_layer_covers_every_numba_module_and_its_imports():
    files = codeversion.compiled_files()
    for rel in (
        "physics/kernels.py",
        "physics/jacobians.py",
        "physics/models.py",
        "physics/params.py",
        "physics/registry.py",
        "solvers/rodas.py",
        "_jit.py",
    ):
        assert rel in files, rel
    # every module that compiles imports njit from the package (never numba's directly), and is in the layer
    for path in PKG.rglob("*.py"):
        text = path.read_text()
        if "@njit" in text:
            assert "from numba import njit" not in text and "_jit import njit" in text, path
            assert path.relative_to(PKG).as_posix() in files, path
    assert len(codeversion.source_hash()) == 64 and codeversion.compiled_hash() != codeversion.source_hash()


def test_hashes_follow_the_file_contents(tmp_path):
    root = tmp_path / "pyfmu_wrapper"
    shutil.copytree(PKG, root, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    h_src, h_cmp = codeversion.source_hash(root), codeversion.compiled_hash(root)
    assert (h_src, h_cmp) == (codeversion.source_hash(PKG), codeversion.compiled_hash(PKG))
    other = tmp_path / "other" / "pyfmu_wrapper"
    shutil.copytree(root, other)
    (other / "generate" / "docs.py").write_text((other / "generate" / "docs.py").read_text() + "\n# edit\n")
    assert codeversion.source_hash(other) != h_src and codeversion.compiled_hash(other) == h_cmp
    (other / "physics" / "params.py").write_text((other / "physics" / "params.py").read_text() + "\n# edit\n")
    for f in (codeversion.source_hash, codeversion.compiled_files, codeversion.compiled_hash):
        f.cache_clear()  # (hashes are cached per process; a new process sees the edit)
    assert codeversion.compiled_hash(other) != h_cmp
