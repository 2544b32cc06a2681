"""Derive the link-level dataset data/brfd_link/ from the BRFD measurements.

Source: D. Coble, P. Huggins, L. Cao, J. Ricles, A. Downey, "Dataset-Friction-Damper-with-Backlash",
ARTS-Lab, GitHub, 2022 (github.com/ARTS-Laboratory/Dataset-Friction-Damper-with-Backlash),
CC BY-SA 4.0. The derived files are under the same licence.

Steps per record: unit conversion to SI (in -> m, kip -> N, in/s -> m/s); keep 3 steady cycles
(the half-cycles whose peak displacement is on the plateau; the start/end ramps are dropped); boxcar-average the force over the decimation stride and
keep every stride-th sample (about 256 samples per cycle). The force is the measured damper
("friction") force column, unchanged in sign.

    python -m pyfmu_wrapper.diagnose.brfd /work/shared/data/brfd data/brfd_link
"""
from __future__ import annotations

import json
import math
import re
import shutil
import sys
from pathlib import Path

import numpy as np
import yaml

from .data import write_record

IN, KIP = 0.0254, 4448.2216
SAMPLES_PER_CYCLE = 256
N_CYCLES = 3
NOMINAL = {"stiffness": 0.0, "damping": 0.0, "friction_force": 11000.0, "friction_slope": 1000.0, "inertance": 0.0}
ATTRIBUTION = """Derived from: D. Coble, P. Huggins, L. Cao, J. Ricles, A. Downey,
"Dataset-Friction-Damper-with-Backlash", ARTS-Lab, GitHub, 2022
(github.com/ARTS-Laboratory/Dataset-Friction-Damper-with-Backlash), "Dataset 2"
characterization tests (April 2023), 30 lb band tension. Licence: Creative Commons
Attribution-ShareAlike 4.0 International (LICENSE.txt). Changes: converted to SI units, trimmed to
3 steady cycles, force boxcar-averaged and decimated to ~256 samples per cycle, CSV format.
Device background: M. Stiles et al., NHERI REU 2019, doi:10.17603/DS2-PT11-YN09; A. Downey,
L. Cao, S. Laflamme, D. Taylor, J. Ricles, Engineering Structures 113 (2016) 287-298."""


def _parse(name):
    m = re.match(r"([\d.]+)Hz30lbtension([\d.]+)amplitude\.json", name)
    return float(m.group(1)), float(m.group(2))


def derive(src: Path, out: Path, test_amplitude_in=1.0, test_frequency_hz=2.0):
    src, out = Path(src), Path(out)
    out.mkdir(parents=True, exist_ok=True)
    recs = []
    for f in sorted(src.glob("*Hz30lbtension*amplitude.json")):
        fhz, amp_in = _parse(f.name)
        raw = json.loads(f.read_text())
        a = np.asarray(raw["data"], dtype=float)
        fs = float(raw["sampling freq"])
        t, d, F, v = a[:, 0], a[:, 1] * IN, a[:, 2] * KIP, a[:, 3] * IN
        n_cyc = int(round(fs / fhz))
        # steady cycles: half-cycles whose peak |d| is within 3 % of the plateau (drop the ramps)
        hc = n_cyc // 2
        peaks = np.array([np.abs(d[k * hc:(k + 1) * hc]).max() for k in range(len(t) // hc)])
        steady = np.nonzero(peaks >= 0.97 * np.median(np.sort(peaks)[len(peaks) // 2:]))[0]
        i0 = int(steady[0]) * hc
        ncyc = min(N_CYCLES, (int(steady[-1]) + 1 - int(steady[0])) * hc // n_cyc)
        i1 = i0 + ncyc * n_cyc
        stride = max(1, int(round(n_cyc / SAMPLES_PER_CYCLE)))
        sl = slice(i0, i1)
        k = (i1 - i0) // stride
        box = lambda x: x[sl][: k * stride].reshape(k, stride).mean(axis=1)
        take = lambda x: x[sl][: k * stride : stride]
        tt = take(t) - t[i0]
        cols = {"t": tt, "displacement": take(d), "velocity": take(v), "force": box(F)}
        # the boxcar delays the force by (stride - 1) / 2 samples: sample the motion at the same time
        if stride > 1:
            shift = (stride - 1) / 2.0 / fs
            cols["displacement"] = np.interp(tt + shift, t[sl] - t[i0], d[sl])
            cols["velocity"] = np.interp(tt + shift, t[sl] - t[i0], v[sl])
        name = f.name.replace(".json", ".csv").replace("30lbtension", "_").replace("amplitude", "in")
        role = "test" if (amp_in == test_amplitude_in or fhz == test_frequency_hz) else "train"
        write_record(out / name, cols, header_comment=f"BRFD {f.name}: SI units (s, m, m/s, N); CC BY-SA 4.0, see README.md")
        recs.append({"file": name, "frequency_hz": fhz, "amplitude": amp_in * IN, "role": role,
                     "source_file": f.name})
    meta = {"level": "link",
            "description": "Banded rotary friction damper with backlash (BRFD), 30 lb band tension, "
                           "sinusoidal displacement tests; link level (displacement across, force through). "
                           "CC BY-SA 4.0, see README.md.",
            "nominal": dict(NOMINAL), "records": recs}
    (out / "dataset.yaml").write_text("# " + ATTRIBUTION.replace("\n", "\n# ") + "\n" + yaml.safe_dump(meta, sort_keys=False))
    shutil.copyfile(src / "LICENSE.txt", out / "LICENSE.txt")
    (out / "README.md").write_text("# BRFD link-level dataset (derived)\n\n" + ATTRIBUTION + "\n\n"
                                   "Nominal model in dataset.yaml: plain Coulomb friction, df = 11 kN "
                                   "(regularised with friction_slope 1e3 s/m). Held-out records (role: test): "
                                   "all 1 in amplitude tests and the 2 Hz test.\n\n"
                                   "Regenerate: `python -m pyfmu_wrapper.diagnose.brfd /work/shared/data/brfd data/brfd_link`\n")
    return recs


if __name__ == "__main__":
    derive(Path(sys.argv[1]), Path(sys.argv[2]))
