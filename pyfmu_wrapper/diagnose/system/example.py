"""The worked example of docs/diagnose.md as data a user can make from the installed package:
``make-benchmark --example swept-sine DIR`` writes it (:func:`write_example`).

``swept-sine``: a base + TMD (Case-1-like nominal: M = 100 kg, K = 4e4 N/m, C = 100 N s/m; m = 9 kg,
k = 4000 N/m, c = 15 N s/m, I = 1 kg, ideal inerter) whose link truly has 10 N s/m more damping than
the nominal; three records of 40 s at 256 Hz, accelerations only (through a 4th-order Butterworth at
100 Hz, declared under ``acquisition``), 1 % white ADC noise, 0.5 % on the load cell: a linear
up-sweep 1.5 -> 5 Hz, a logarithmic down-sweep 5 -> 1.5 Hz (150 N each), and a free decay released
from (x, y) = (5, 10) mm (``kind: decay``, no force column). The truth is simulated by
:mod:`.transient_truth`'s own integrator at 8 x 256 Hz, seed 0 (the same numbers as
tests/test_diagnose_transient.py's ``make`` with those arguments, which the tests hold equal).
"""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

BASE = {"mass": 100.0, "stiffness": 4.0e4, "damping": 100.0, "force_amplitude": 200.0}
TMD = {"mass": 9.0, "stiffness": 4.0e3, "damping": 15.0, "inertance": 1.0, "inerter": "ideal"}
FILTER = {"filter": {"type": "butterworth", "order": 4, "cutoff_hz": 100.0}}
NOISE = {"x": 0.01, "y": 0.01, "xdd": 0.01, "ydd": 0.01, "force": 0.005}
#: the records of each example: (kind, force-signal arguments)
EXAMPLES: dict[str, dict[str, Any]] = {
    "swept-sine": {
        "records": [("sweep_lin", {"f0": 1.5, "f1": 5.0}), ("sweep_log", {"f0": 5.0, "f1": 1.5}), ("decay", {})],
        "changes": {"dc": 10.0},
        "fs": 256.0,
        "seconds": 40.0,
        "seed": 0,
        "accel_only": True,
        "description": "docs/diagnose.md's worked example: the link has 10 N s/m more damping than the nominal",
    }
}


def write_example(name: str, path: Path | str) -> list[str]:
    """Write the example ``name`` (of :data:`EXAMPLES`) into the folder ``path`` (dataset.yaml and the
    CSV records); returns the files written."""
    import numpy as np
    import yaml

    from ..records import write_record
    from .transient_truth import Truth, force_signal, measure

    ex = EXAMPLES[name]
    path = Path(path)
    path.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(ex["seed"])
    fs, T = ex["fs"], ex["seconds"]
    acq = {"xdd": copy.deepcopy(FILTER), "ydd": copy.deepcopy(FILTER)}  # written out twice, no YAML alias
    recs, files = [], []
    for i, (kind, kw) in enumerate(ex["records"]):
        kw = dict(kw)
        t = np.arange(0.0, T, 1.0 / (8 * fs))
        F = force_signal(kind, rng, T, kw.pop("amp", 150.0), **kw)
        z0 = np.array([0.005, 0.0, 0.01, 0.0]) if kind == "decay" else None
        sig = Truth(BASE, TMD, T, **ex["changes"]).simulate(F, t, z0)
        if kind == "decay":
            sig.pop("force")
        m = measure(sig, t, 8, rng, NOISE, acq)
        if ex["accel_only"]:
            m.pop("x"), m.pop("y")
        write_record(path / f"r{i}.csv", m)
        recs.append({"file": f"r{i}.csv", "kind": "decay" if kind == "decay" else "transient"})
        files.append(f"r{i}.csv")
    doc = {
        "level": "system",
        "description": ex["description"],
        "nominal": {"base": BASE, "tmd": TMD},
        "records": recs,
        "acquisition": acq,
    }
    (path / "dataset.yaml").write_text(yaml.safe_dump(doc, sort_keys=False), encoding="utf-8")
    return ["dataset.yaml", *files]
