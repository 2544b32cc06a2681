"""Every script of benchmarks/ loads: every project name it imports exists (a script is run only when
a benchmark is wanted, so a moved name would otherwise go unnoticed). Loading runs no benchmark: each
script's work sits under ``__main__``."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

SCRIPTS = sorted((Path(__file__).resolve().parents[1] / "benchmarks").glob("*.py"))


def test_the_benchmarks_folder_holds_scripts():
    assert len(SCRIPTS) >= 10


@pytest.mark.parametrize("script", SCRIPTS, ids=lambda p: p.name)
def test_benchmark_script_loads(script, monkeypatch):
    name = f"_bench_{script.stem}"
    spec = importlib.util.spec_from_file_location(name, script)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, name, mod)  # dataclasses look their module up while loading
    spec.loader.exec_module(mod)
    assert callable(getattr(mod, "main", None)) or any(
        callable(v) for k, v in vars(mod).items() if k.startswith("bench")
    )
