"""Derive the link-level dataset data/brfd_link/ from the BRFD measurements.

Source: D. Coble, P. Huggins, L. Cao, J. Ricles, A. Downey, "Dataset-Friction-Damper-with-Backlash",
ARTS-Lab, GitHub, 2022 (github.com/ARTS-Laboratory/Dataset-Friction-Damper-with-Backlash),
CC BY-SA 4.0. The derived files are under the same licence.

Steps per record: unit conversion to SI (in -> m, kip -> N, in/s -> m/s); keep 3 steady cycles
(the half-cycles whose peak displacement is on the plateau; the start/end ramps are dropped); boxcar-average the force over the decimation stride and
keep every stride-th sample (about 256 samples per cycle). The force is the measured damper
("friction") force column, unchanged in sign.

    python -m pyfmu_wrapper.diagnose.link.brfd BRFD_DIR data/brfd_link --dataset '"Dataset 2" (April 2023)'
"""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import yaml

from ..records import write_record

if TYPE_CHECKING:
    from typing import Any

IN, KIP = 0.0254, 4448.2216
SAMPLES_PER_CYCLE = 256
N_CYCLES = 3
NOMINAL = {"stiffness": 0.0, "damping": 0.0, "friction_force": 11000.0, "friction_slope": 1000.0, "inertance": 0.0}
ATTRIBUTION = """Derived from: D. Coble, P. Huggins, L. Cao, J. Ricles, A. Downey,
"Dataset-Friction-Damper-with-Backlash", ARTS-Lab, GitHub, 2022
(github.com/ARTS-Laboratory/Dataset-Friction-Damper-with-Backlash), {dataset}
characterization tests, {tension} band tension. Licence: Creative Commons
Attribution-ShareAlike 4.0 International (LICENSE.txt). Changes: converted to SI units, trimmed to
3 steady cycles, force boxcar-averaged and decimated to ~256 samples per cycle, CSV format.
Device background: M. Stiles et al., NHERI REU 2019, doi:10.17603/DS2-PT11-YN09; A. Downey,
L. Cao, S. Laflamme, D. Taylor, J. Ricles, Engineering Structures 113 (2016) 287-298."""


NAME = re.compile(
    r"(?P<f>\d+(?:\.\d+)?)\s*Hz[_\s-]*(?P<tension>\d+(?:\.\d+)?)\s*lb\s*tension[_\s-]*"
    r"(?P<a>\d+(?:\.\d+)?)\s*(?:in)?\s*amplitude",
    re.IGNORECASE,
)


def _parse(name: str) -> tuple[float, float, float] | None:
    """(frequency [Hz], amplitude [in], tension [lb]) from a BRFD file name such as
    ``0.5Hz30lbtension1amplitude.json`` or ``2Hz_45lbtension_0.5inamplitude.json``; None if not one."""
    m = NAME.search(name)
    if m is None:
        return None
    return float(m.group("f")), float(m.group("a")), float(m.group("tension"))


def _dataset_label(src: Path) -> str:
    m = re.search(r"data[\s_-]*set[\s_-]*(\d+)", str(src), re.IGNORECASE)
    return f'"Dataset {m.group(1)}"' if m else f'the "{src.name}" files'


def derive(
    src: Path,
    out: Path,
    test_amplitude_in: float = 1.0,
    test_frequency_hz: float = 2.0,
    tension_lb: float | None = None,
    dataset: str | None = None,
) -> list[Any]:
    """Derive the link-level dataset from the BRFD JSON files in ``src`` (any band tension and file
    naming read by :func:`_parse`; with several tensions, pick one with ``tension_lb``)."""
    src, out = Path(src), Path(out)
    files = [(f, p) for f in sorted(src.glob("*.json")) if (p := _parse(f.name)) is not None]
    tensions = sorted({p[2] for _, p in files})
    if not files:
        raise ValueError(f"{src}: no BRFD files named like '<f>Hz<T>lbtension<A>amplitude.json'")
    if tension_lb is None:
        if len(tensions) > 1:
            raise ValueError(f"{src}: files for several band tensions {tensions} lb: choose one (tension_lb)")
        tension_lb = tensions[0]
    files = [(f, p) for f, p in files if p[2] == tension_lb]
    dataset = dataset or _dataset_label(src)
    attribution = ATTRIBUTION.format(dataset=dataset, tension=f"{tension_lb:g} lb")
    out.mkdir(parents=True, exist_ok=True)
    recs = []
    for f, (fhz, amp_in, _) in files:
        raw = json.loads(f.read_text())
        a = np.asarray(raw["data"], dtype=float)
        fs = float(raw["sampling freq"])
        t, d, F, v = a[:, 0], a[:, 1] * IN, a[:, 2] * KIP, a[:, 3] * IN
        n_cyc = int(round(fs / fhz))
        # steady cycles: half-cycles whose peak |d| is within 3 % of the plateau (drop the ramps)
        hc = n_cyc // 2
        peaks = np.array([np.abs(d[k * hc : (k + 1) * hc]).max() for k in range(len(t) // hc)])
        steady = np.nonzero(peaks >= 0.97 * np.median(np.sort(peaks)[len(peaks) // 2 :]))[0]
        i0 = int(steady[0]) * hc
        ncyc = min(N_CYCLES, (int(steady[-1]) + 1 - int(steady[0])) * hc // n_cyc)
        i1 = i0 + ncyc * n_cyc
        stride = max(1, int(round(n_cyc / SAMPLES_PER_CYCLE)))
        sl = slice(i0, i1)
        k = (i1 - i0) // stride

        def box(x: np.ndarray, sl: slice = sl, k: int = k, stride: int = stride) -> np.ndarray:
            return x[sl][: k * stride].reshape(k, stride).mean(axis=1)

        def take(x: np.ndarray, sl: slice = sl, k: int = k, stride: int = stride) -> np.ndarray:
            return x[sl][: k * stride : stride]

        tt = take(t) - t[i0]
        cols = {"t": tt, "displacement": take(d), "velocity": take(v), "force": box(F)}
        # the boxcar delays the force by (stride - 1) / 2 samples: sample the motion at the same time
        if stride > 1:
            shift = (stride - 1) / 2.0 / fs
            cols["displacement"] = np.interp(tt + shift, t[sl] - t[i0], d[sl])
            cols["velocity"] = np.interp(tt + shift, t[sl] - t[i0], v[sl])
        name = f"{fhz:g}Hz_{amp_in:g}in.csv"
        role = "test" if (amp_in == test_amplitude_in or fhz == test_frequency_hz) else "train"
        write_record(
            out / name, cols, header_comment=f"BRFD {f.name}: SI units (s, m, m/s, N); CC BY-SA 4.0, see README.md"
        )
        recs.append({"file": name, "frequency_hz": fhz, "amplitude": amp_in * IN, "role": role, "source_file": f.name})
    meta = {
        "level": "link",
        "description": f"Banded rotary friction damper with backlash (BRFD), {tension_lb:g} lb band tension, "
        "sinusoidal displacement tests; link level (displacement across, force through). "
        "CC BY-SA 4.0, see README.md.",
        "nominal": dict(NOMINAL),
        "records": recs,
    }
    (out / "dataset.yaml").write_text(
        "# " + attribution.replace("\n", "\n# ") + "\n" + yaml.safe_dump(meta, sort_keys=False)
    )
    shutil.copyfile(src / "LICENSE.txt", out / "LICENSE.txt")
    (out / "README.md").write_text(
        "# BRFD link-level dataset (derived)\n\n" + attribution + "\n\n"
        "Nominal model in dataset.yaml: plain Coulomb friction, df = 11 kN "
        "(regularised with friction_slope 1e3 s/m). Held-out records (role: test): "
        "all 1 in amplitude tests and the 2 Hz test.\n\n"
        "Regenerate: `python -m pyfmu_wrapper.diagnose.link.brfd BRFD_DIR data/brfd_link`, with BRFD_DIR a copy of the ARTS-Lab repository above\n"
    )
    return recs


if __name__ == "__main__":
    import argparse

    ap = argparse.ArgumentParser(description="Derive the BRFD link-level dataset (see module doc).")
    ap.add_argument("src")
    ap.add_argument("out")
    ap.add_argument("--tension", type=float, help="band tension [lb] when the folder holds several")
    ap.add_argument("--dataset", help="label written in the header, e.g. '\"Dataset 2\" (April 2023)'")
    a = ap.parse_args()
    derive(Path(a.src), Path(a.out), tension_lb=a.tension, dataset=a.dataset)
