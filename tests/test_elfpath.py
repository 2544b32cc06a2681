"""Run paths of bundled ELF files (pyfmu_wrapper/fmubuild/elfpath.py), checked against ``readelf -d`` and the
dynamic loader: a shared object linked with a RUNPATH into a build folder gets an ``$ORIGIN``-relative
one and still loads and runs."""

from __future__ import annotations

import ctypes
import shutil
import subprocess

import pytest

from pyfmu_wrapper.fmubuild.elfpath import run_paths, set_run_path

pytestmark = pytest.mark.skipif(shutil.which("gcc") is None or shutil.which("readelf") is None, reason="needs gcc")


def _readelf_paths(so):
    d = subprocess.run(["readelf", "-d", str(so)], capture_output=True, text=True, check=True).stdout
    return [line.split("[", 1)[1].rstrip("]") for line in d.splitlines() if "RUNPATH" in line or "RPATH" in line]


@pytest.mark.parametrize("tags", ["--enable-new-dtags", "--disable-new-dtags"], ids=["RUNPATH", "RPATH"])
def test_run_path_rewritten_in_place_and_the_library_still_loads(tmp_path, tags):
    src = tmp_path / "f.c"
    src.write_text("int answer(int x) { return 2 * x + 1; }\n")
    so = tmp_path / "libf.so"
    build = "/root/.pyenv/versions/3.11.7/lib:/opt/build/lib"
    subprocess.run(["gcc", "-shared", "-fPIC", str(src), "-o", str(so), f"-Wl,{tags},-rpath,{build}"], check=True)
    assert run_paths(so) == _readelf_paths(so) == [build]
    assert set_run_path(so, "$ORIGIN/../..")
    assert run_paths(so) == _readelf_paths(so) == ["$ORIGIN/../.."]
    assert ctypes.CDLL(str(so)).answer(20) == 41
    # longer than the old string: emptied, never written past it (a copy: the first is mapped now)
    so2 = tmp_path / "libf2.so"
    shutil.copyfile(so, so2)
    assert set_run_path(so2, "$ORIGIN/" + "x" * 100)
    assert run_paths(so2) == [""]
    assert ctypes.CDLL(str(so2)).answer(1) == 3


def test_files_without_a_run_path_are_left_alone(tmp_path):
    src = tmp_path / "g.c"
    src.write_text("int g(void) { return 7; }\n")
    so = tmp_path / "libg.so"
    subprocess.run(["gcc", "-shared", "-fPIC", str(src), "-o", str(so)], check=True)
    before = so.read_bytes()
    assert run_paths(so) == [] and not set_run_path(so, "$ORIGIN")
    assert so.read_bytes() == before
    text = tmp_path / "t.so.txt"
    text.write_text("not an ELF file")
    assert run_paths(text) == [] and not set_run_path(text, "$ORIGIN")
