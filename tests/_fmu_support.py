"""Shared helpers of the FMU tests: built FMUs, extraction, exact reference solutions."""

from __future__ import annotations

import math
import subprocess
import zipfile
from pathlib import Path

import numpy as np

from pyfmu_wrapper.fmubuild.build import DEFAULT_OUT, ensure_fmus, fmi_headers_dir
from pyfmu_wrapper.models.catalog import SPECS, pick

C_HOST_SOURCE = Path(__file__).parent / "c_host" / "fmu_host.c"


def built_fmus() -> dict[str, Path]:
    return ensure_fmus(pick(("BaseOscillator", "TMDInerter", "Trivial")), out_dir=DEFAULT_OUT)


def every_fmu() -> dict[str, Path]:
    """Every declared FMU (every registered unit's, and Trivial), Python-hosted, FMI 2.0."""
    return ensure_fmus(pick(SPECS), out_dir=DEFAULT_OUT)


def extract(fmu: Path, root: Path) -> Path:
    """Unzip an FMU into root/<modelIdentifier> (the C host derives the binary name from it)."""
    d = root / fmu.stem
    d.mkdir(parents=True, exist_ok=True)
    with zipfile.ZipFile(fmu) as z:
        z.extractall(d)
    return d


def guid(fmu_dir: Path) -> str:
    for line in (fmu_dir / "resources" / "pyfmu.cfg").read_text().splitlines():
        if line.startswith("guid="):
            return line[5:]
    raise KeyError("guid")


def compile_c_host(out: Path) -> Path:
    exe = out / "fmu_host"
    subprocess.run(
        ["gcc", "-O2", "-Wall", f"-I{fmi_headers_dir()}", str(C_HOST_SOURCE), "-o", str(exe), "-ldl"],
        check=True,
        capture_output=True,
        text=True,
    )
    return exe


def damped_forced_response(t, M, K, C, F, w, x0, xd0):
    """Exact x(t), xd(t) of M xdd + C xd + K x = F cos(w t), x(0) = x0, xd(0) = xd0 (underdamped).

    Particular solution A cos(wt) + B sin(wt); homogeneous e^(-zeta wn t)(c1 cos wd t + c2 sin wd t).
    """
    t = np.asarray(t, dtype=float)
    den = (K - M * w * w) ** 2 + (C * w) ** 2
    A = F * (K - M * w * w) / den
    B = F * C * w / den
    a = C / (2 * M)
    wd = math.sqrt(K / M - a * a)
    c1 = x0 - A
    c2 = (xd0 - B * w + a * c1) / wd
    e = np.exp(-a * t)
    x = A * np.cos(w * t) + B * np.sin(w * t) + e * (c1 * np.cos(wd * t) + c2 * np.sin(wd * t))
    xd = (
        -A * w * np.sin(w * t)
        + B * w * np.cos(w * t)
        + e * (-a * (c1 * np.cos(wd * t) + c2 * np.sin(wd * t)) + wd * (-c1 * np.sin(wd * t) + c2 * np.cos(wd * t)))
    )
    return x, xd


FUZZ_SOURCE = Path(__file__).parent / "c_host" / "fmu_fuzz.c"


def compile_fuzz(out: Path) -> Path:
    exe = out / "fmu_fuzz"
    subprocess.run(
        ["gcc", "-O2", "-Wall", f"-I{fmi_headers_dir()}", str(FUZZ_SOURCE), "-o", str(exe), "-ldl", "-lm"],
        check=True,
        capture_output=True,
        text=True,
    )
    return exe


def run_fuzz(
    root: Path,
    sequences: int,
    calls: int,
    seed: int = 1,
    timeout: float = 3600,
    names: tuple[str, str] = ("BaseOscillator", "TMDInerter"),
) -> dict[str, int]:
    """Run the C fuzz harness (one forked subprocess per sequence) on copies of two FMUs."""
    import os

    fmus = ensure_fmus(pick(names), out_dir=DEFAULT_OUT)
    dirs = [extract(fmus[n], root) for n in names]
    exe = compile_fuzz(root)
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTHON", "LD_PRELOAD", "VIRTUAL_ENV"))}
    r = subprocess.run(
        [str(exe), str(seed), str(sequences), str(calls), str(dirs[0]), guid(dirs[0]), str(dirs[1]), guid(dirs[1])],
        capture_output=True,
        text=True,
        env=env,
        timeout=timeout,
    )
    if r.returncode != 0:
        raise RuntimeError(f"fuzz harness failed ({r.returncode}): {r.stderr[-3000:]}")
    out = {k: int(v) for k, v in (line.split() for line in r.stdout.splitlines() if line.strip())}
    out["stderr"] = r.stderr  # type: ignore[assignment]
    return out
