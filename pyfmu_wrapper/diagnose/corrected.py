"""Close the loop: the corrected model a system-level diagnosis writes back (``OUT/corrected/``).

The nominal of the dataset with the named effects added at their fitted values, by the unit's own
vocabulary (:meth:`pyfmu_wrapper.physics.effects.Vocabulary.changed`: each effect parameter's
targets, the registry's bounds), written as

* scenario files (``corrected_F<force>N.yaml``, the schema of ``scenarios/*.yaml``, read by
  ``run-scenario``'s loader), one per force amplitude of the dataset's steady and FRC records (a
  scenario has one force amplitude), at those records' frequencies; one FRC study whose curves are
  the corrected model and, for comparison, the nominal TMD;
* the same parameter sets as SSP 1.0 parameter files (``corrected_F<force>N.ssv``) named by the
  variables of the project's FMUs (``base.M``, ``tmd.k``, ...: instance ``base`` is BaseOscillator,
  ``tmd`` is TMDInerter, as in :func:`pyfmu_wrapper.models.base_tmd.cosim.export_tmd_system`).

What is not a model parameter is said in each file's description, not folded in: a named
``force_error`` (true force = (1 + a) x recorded) sets the scenario's force amplitude to (1 + a) x the
recorded one; a ``sensor_offset`` is the sensor's (the model is unchanged by it); nuisance parameters
of a fit (``play.delta_inertance_eff``) are not applied. When nothing is named, the corrected model is
the nominal, and the description says so.

:func:`measured_points` and :func:`chi2_per_point` compare ``run-scenario``'s curves with the records
in units of their noise (the FRC records' x_max noise of :class:`.system.frc.FRCDiagnosis`; a steady
record's max |x| from its harmonic series, with the series' own variance), as
``benchmarks/bench_corrected.py`` and the tests do.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any
from xml.sax.saxutils import quoteattr

import numpy as np

if TYPE_CHECKING:
    from .data import Dataset

#: SSP instance name of each subsystem (as the project's SSP export names them) and its FMU
INSTANCES = {"base": "BaseOscillator", "tmd": "TMDInerter"}
_NS_SSV = "http://ssp-standard.org/SSP1/SystemStructureParameterValues"


def _vocab() -> Any:
    from .system.effects import VOCAB

    return VOCAB


def corrected_params(nominal: Mapping[str, Mapping[str, Any]], parameters: Mapping[str, Any]) -> tuple[Any, Any, dict]:
    """(BaseParams, TMDParams, notes) of ``nominal`` (``{"base": {...}, "tmd": {...}}``) changed by the
    verdict's ``parameters`` (``effect.parameter`` -> value or ``{"value": ...}``) through the
    vocabulary; ``notes``: ``applied`` (key -> value), ``force_gain`` (1 + a), ``not_applied`` (key ->
    why)."""
    from ..physics.params import BaseParams, InerterModel, TMDParams

    vocab = _vocab()
    base = BaseParams(**nominal["base"])
    tmd = TMDParams(**nominal["tmd"])
    applied: dict[str, float] = {}
    not_applied: dict[str, str] = {}
    gain = 1.0
    for key, v in parameters.items():
        val = float(v["value"] if isinstance(v, Mapping) else v)
        eff, _, name = key.partition(".")
        if eff not in vocab or name not in vocab[eff].param_names:
            not_applied[key] = "a nuisance parameter of the fit, not a model parameter"
            continue
        par = vocab[eff].param(name)
        if eff == "force_error":
            gain = 1.0 + val
            continue
        if not par.targets:
            not_applied[key] = f"a measurement effect ({vocab[eff].label}): the sensor's, not the model's"
            continue
        if not math.isfinite(val):
            not_applied[key] = f"not finite ({val})"
            continue
        applied[key] = val
    changed = vocab.changed({"base": base, "tmd": tmd}, applied)
    base, tmd = changed["base"], changed["tmd"]
    if tmd.play_gap > 0.0 and tmd.inerter != InerterModel.PLAY:  # a gap needs the play chain
        import dataclasses

        tmd = dataclasses.replace(tmd, inerter=InerterModel.PLAY)
    return base, tmd, {"applied": applied, "force_gain": gain, "not_applied": not_applied}


def record_points(ds: Dataset) -> dict[float, list[float]]:
    """Force amplitude [N] (as recorded) -> the sorted frequencies [rad/s] of the dataset's steady
    time records and FRC points at that force."""
    out: dict[float, set[float]] = {}
    for r in ds.records:
        if r.kind == "time" and r.omega:
            F = _record_force(r)
            out.setdefault(F, set()).add(float(r.omega))
        elif r.kind == "frc":
            for w, F in zip(r["omega"], r["force_amplitude"], strict=True):
                out.setdefault(_round_force(float(F)), set()).add(float(w))
    return {F: sorted(ws) for F, ws in sorted(out.items())}


def _round_force(F: float) -> float:
    return float(f"{F:.6g}")


def _record_force(r: Any) -> float:
    if r.amplitude:
        return _round_force(float(r.amplitude))
    from ..solvers.harmonic import fit_series

    s = fit_series(np.asarray(r["t"], float), {"force": r["force"]}, float(r.omega), 1)
    return _round_force(abs(complex(s.coef["force"][1])))


def _fmt(x: float) -> str:
    return repr(float(x))


def _name(F: float) -> str:
    return f"corrected_F{F:g}N".replace("+", "")


def write_corrected(ds: Dataset, res: Mapping[str, Any], folder: Path) -> list[Path]:
    """Write ``folder`` (new: the caller's fresh result folder) with the corrected scenario files and
    their .ssv parameter sets; returns the files written. System level only."""
    import yaml

    from ..physics.params import as_dict

    verdict = res.get("verdict") or {}
    if "frame" in ds.nominal:
        return write_corrected_frame(ds, verdict, folder)
    effects = list(verdict.get("effects") or [])
    params = verdict.get("parameters") or {}
    base, tmd, notes = corrected_params(ds.nominal, {k: v for k, v in params.items() if k.split(".")[0] in effects})
    nom_tmd = as_dict(type(tmd)(**ds.nominal["tmd"]))
    points = record_points(ds)
    grid_note = ""
    if not points:  # transient records only: a band around the structure's resonances
        wn = math.sqrt(base.stiffness / base.mass)
        points = {_round_force(base.force_amplitude): [float(w) for w in np.linspace(0.75 * wn, 1.25 * wn, 41)]}
        grid_note = " The dataset has no steady or FRC record: the frequencies are 0.75-1.25 sqrt(K/M)."
    if effects:
        elements = list(verdict.get("elements") or [""] * len(effects))
        what = "; ".join(f"{e} ({el})" if el else e for e, el in zip(effects, elements, strict=False))
        vals = ", ".join(f"{k} = {v:.6g}" for k, v in notes["applied"].items())
        desc = f"The nominal of {ds.path.name} corrected by diagnose: {what} named; applied {vals or 'no change of a model parameter'}."
        if notes["force_gain"] != 1.0:
            desc += (
                f" force_error: true force = {notes['force_gain']:.6g} x recorded, so force_amplitude is the "
                "recorded one times that."
            )
        for k, why in notes["not_applied"].items():
            desc += f" Not applied: {k} ({why})."
    else:
        desc = (
            f"The nominal of {ds.path.name} unchanged: diagnose named no effect, so the corrected model is the nominal."
        )
    desc += (
        grid_note + " Frequencies: those of the dataset's steady and FRC records at this force (as recorded: "
        "{F} N). Curve 'nominal': the nominal TMD on this base block."
    )
    folder.mkdir(parents=True, exist_ok=False)
    written = []
    tmd_block = as_dict(tmd)
    base_block = as_dict(base)
    for F, omegas in points.items():
        Fm = F * notes["force_gain"]
        name = _name(F)
        doc = {
            "schema_version": 2,
            "name": name,
            "description": desc.replace("{F}", f"{F:g}"),
            "base": {**base_block, "force_amplitude": Fm},
            "tmd": tmd_block,
            "frequencies": [float(w) for w in omegas],
            "sweep": {"direction": "up", "continuation": False},
            "studies": [
                {
                    "kind": "frc",
                    "name": "corrected",
                    "title": f"corrected model at F = {Fm:g} N",
                    "curves": [
                        {"label": "corrected" if effects else "corrected (= nominal)"},
                        {"label": "nominal", "tmd": nom_tmd},
                    ],
                }
            ],
        }
        p = folder / f"{name}.yaml"
        p.write_text(
            "# written by diagnose (the corrected model, docs/diagnose.md 'The corrected model')\n"
            + yaml.safe_dump(doc, sort_keys=False, width=100),
            encoding="utf-8",
        )
        q = folder / f"{name}.ssv"
        values = {"base": {**base_block, "force_amplitude": Fm}, "tmd": tmd_block}
        q.write_text(ssv_text(name, values, desc.replace("{F}", f"{F:g}")), encoding="utf-8")
        written += [p, q]
    return written


def corrected_frame(nominal: Mapping[str, Any], parameters: Mapping[str, Any]) -> tuple[dict, dict, dict]:
    """(frame block, tmd block, notes) of a frame nominal (:func:`pyfmu_wrapper.diagnose.data.
    normalise_frame_nominal`) with the verdict's ``parameters`` (``effect@element.parameter`` -> value
    or ``{"value": ...}``) applied by the frame unit's vocabulary: a storey effect changes that storey's
    entry of the frame's per-storey list, a TMD effect the TMD's field (each parameter's registry
    target, :class:`~pyfmu_wrapper.physics.effects.EffectParam`); ``force_error`` gives ``force_gain``
    (true = recorded / (1 + g)); a channel gain is the sensor's (``not_applied``)."""
    from ..models.frame_model import UNIT

    vocab = UNIT.effects
    assert vocab is not None
    fr = {k: (list(v) if isinstance(v, list) else v) for k, v in nominal["frame"].items()}
    td = dict(nominal["tmd"])
    applied: dict[str, float] = {}
    not_applied: dict[str, str] = {}
    gain = 1.0
    for key, v in parameters.items():
        val = float(v["value"] if isinstance(v, Mapping) else v)
        head, _, name = key.partition(".")
        eff, _, element = head.partition("@")
        if eff == "friction" and name == "log10_friction_slope" and math.isfinite(val):  # the law's fitted slope
            td["friction_slope"] = 10.0**val
            applied[key] = val
            continue
        if eff not in vocab or name not in vocab[eff].param_names or not math.isfinite(val):
            not_applied[key] = "not a parameter of the frame's vocabulary"
            continue
        par = vocab[eff].param(name)
        if eff == "force_error":
            gain = 1.0 / (1.0 + val)
            continue
        if not par.targets:
            not_applied[key] = f"a measurement effect ({vocab[eff].label}): the sensor's, not the model's"
            continue
        for target, coef in par.targets:
            sub, field = target.split(".")
            if sub == "frame":
                i = int(element.split()[-1]) - 1
                fr[field][i] = float(fr[field][i]) + coef * val
            elif par.replaces:
                td[field] = val
            else:
                td[field] = float(td.get(field, 0.0)) + coef * val
        applied[key] = val
    return fr, td, {"applied": applied, "force_gain": gain, "not_applied": not_applied}


def write_corrected_frame(ds: Dataset, verdict: Mapping[str, Any], folder: Path) -> list[Path]:
    """The corrected frame (:func:`corrected_frame`) as a scenario (``corrected_frame.yaml``: frame:/tmd:
    blocks with per-storey lists, an FRC study of the corrected and the nominal TMD around the nominal's
    modes) and its FrameSystem parameter set (``corrected_frame.ssv``)."""
    import yaml

    from .frame.model import FrameModel

    effects = list(verdict.get("effects") or [])
    params = verdict.get("parameters") or {}
    fr, td, notes = corrected_frame(ds.nominal, params)
    F = max((float(np.max(np.abs(r["force"]))) for r in ds.records if r.has("force")), default=0.0)
    F = _round_force(F) if F > 0 else float(ds.nominal["frame"].get("force_amplitude", 200.0))
    F *= notes["force_gain"]
    modes = FrameModel.from_nominal(ds.nominal).modes_hz()
    w = 2 * math.pi * np.linspace(0.7 * modes[0], 1.3 * modes[-1], 81)
    if effects:
        what = "; ".join(f"{e} at {el}" for e, el in zip(effects, verdict.get("elements") or [], strict=False))
        vals = ", ".join(f"{k} = {v:.6g}" for k, v in notes["applied"].items())
        desc = f"The nominal of {ds.path.name} corrected by diagnose: {what} named; applied {vals or 'no change of a model parameter'}."
        if notes["force_gain"] != 1.0:
            desc += f" force_error: the true force is {notes['force_gain']:.6g} x the recorded one."
        for k, why in notes["not_applied"].items():
            desc += f" Not applied: {k} ({why})."
    else:
        desc = f"The nominal of {ds.path.name} unchanged: diagnose named no effect."
    desc += f" force_amplitude: the records' largest |force| ({F:g} N); frequencies 0.7 x the lowest to 1.3 x the highest nominal mode."
    nom_tmd = {k: v for k, v in ds.nominal["tmd"].items() if k not in ("storey", "inerter_to")}
    frame_block = {
        "storeys": int(fr["storeys"]),
        "mass": [float(x) for x in fr["mass"]],
        "stiffness": [float(x) for x in fr["stiffness"]],
        "damping": [float(x) for x in fr["damping"]],
        "force_amplitude": F,
        "force_storey": int(fr["force_storey"]),
    }
    tmd_block = {
        k: (float(v) if isinstance(v, (int, float)) and k not in ("storey", "inerter_to") else v) for k, v in td.items()
    }
    doc = {
        "schema_version": 2,
        "name": "corrected_frame",
        "description": desc,
        "frame": frame_block,
        "tmd": tmd_block,
        "frequencies": [float(x) for x in w],
        "sweep": {"direction": "up", "continuation": False},
        "studies": [
            {
                "kind": "frc",
                "name": "corrected",
                "title": "corrected frame",
                "curves": [
                    {"label": "corrected" if effects else "corrected (= nominal)"},
                    {"label": "nominal", "tmd": nom_tmd},
                ],
            }
        ],
    }
    folder.mkdir(parents=True, exist_ok=False)
    p = folder / "corrected_frame.yaml"
    p.write_text(
        "# written by diagnose (the corrected model, docs/diagnose.md 'The corrected model')\n"
        + yaml.safe_dump(doc, sort_keys=False, width=100),
        encoding="utf-8",
    )
    q = folder / "corrected_frame.ssv"
    q.write_text(frame_ssv_text("corrected_frame", frame_block, tmd_block, desc), encoding="utf-8")
    return [p, q]


def frame_ssv_text(name: str, frame: Mapping[str, Any], tmd: Mapping[str, Any], description: str = "") -> str:
    """An SSP 1.0 parameter set of the FrameSystem FMU (:mod:`pyfmu_wrapper.models.frame_model.fmus.
    system_variables`): ``storeys``, ``m<i>``, ``k<i>``, ``c<i>``, ``F``, ``force_storey``,
    ``tmd_storey``, ``inerter_to`` and the TMD's parameters under their FrameSystem names."""
    from ..models.frame_model.fmus.system_variables import tmd_name
    from ..physics import registry
    from ..physics.params import InerterModel

    rows: list[tuple[str, Any, str]] = [("storeys", int(frame["storeys"]), "")]
    for key, sym, unit in (("mass", "m", "kg"), ("stiffness", "k", "N/m"), ("damping", "c", "N.s/m")):
        rows += [(f"{sym}{i + 1}", float(v), unit) for i, v in enumerate(frame[key])]
    rows += [("F", float(frame["force_amplitude"]), "N"), ("force_storey", int(frame["force_storey"]), "")]
    rows += [("tmd_storey", int(tmd["storey"]), ""), ("inerter_to", int(tmd["inerter_to"]), "")]
    for field, v in tmd.items():
        if field in ("storey", "inerter_to"):
            continue
        row = registry.get("tmd", field)
        if row.kind == "enum":
            rows.append((tmd_name(row.fmu_name), int(InerterModel[v.upper()]) if isinstance(v, str) else int(v), ""))
        else:
            rows.append((tmd_name(row.fmu_name), float(v), registry.get("tmd", field).unit))
    lines = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        f'<ssv:ParameterSet xmlns:ssv="{_NS_SSV}" version="1.0" name={quoteattr(name)}'
        + (f" description={quoteattr(description)}>" if description else ">"),
        "  <ssv:Parameters>",
    ]
    for key, v, unit in rows:
        if isinstance(v, int):
            lines.append(f'    <ssv:Parameter name={quoteattr(key)}><ssv:Integer value="{v}"/></ssv:Parameter>')
        else:
            u = f" unit={quoteattr(unit)}" if unit else ""
            lines.append(f'    <ssv:Parameter name={quoteattr(key)}><ssv:Real value="{_fmt(v)}"{u}/></ssv:Parameter>')
    lines += ["  </ssv:Parameters>", "</ssv:ParameterSet>"]
    return "\n".join(lines) + "\n"


def ssv_text(name: str, values: Mapping[str, Mapping[str, Any]], description: str = "") -> str:
    """An SSP 1.0 parameter set (``ssv:ParameterSet``) of the subsystems' parameters ``values``
    (``{"base": {"mass": ...}, "tmd": {...}}``, registry names) under the FMU variable names
    (``base.M``, ``tmd.k``: the FMUs' variable tables, :mod:`pyfmu_wrapper.models.base_tmd.fmus.variables`),
    with the units the FMUs declare; the inerter model as an integer (its enumeration code)."""
    from ..models.base_tmd.fmus.variables import BASE_OSCILLATOR, TMD_INERTER
    from ..physics import registry
    from ..physics.params import InerterModel

    specs = {"base": BASE_OSCILLATOR, "tmd": TMD_INERTER}
    lines = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        f'<ssv:ParameterSet xmlns:ssv="{_NS_SSV}" version="1.0" name={quoteattr(name)}'
        + (f" description={quoteattr(description)}>" if description else ">"),
        "  <ssv:Parameters>",
    ]
    for sub, vals in values.items():
        for field, v in vals.items():
            row = registry.get(sub, field)
            var = specs[sub].by_name(row.fmu_name)
            key = quoteattr(f"{sub}.{var.name}")
            if row.kind == "enum":
                code = int(InerterModel[v.upper()]) if isinstance(v, str) else int(v)
                lines.append(f'    <ssv:Parameter name={key}><ssv:Integer value="{code}"/></ssv:Parameter>')
            else:
                unit = f" unit={quoteattr(var.unit)}" if var.unit else ""
                lines.append(f'    <ssv:Parameter name={key}><ssv:Real value="{_fmt(v)}"{unit}/></ssv:Parameter>')
    lines.append("  </ssv:Parameters>")
    lines.append("</ssv:ParameterSet>")
    return "\n".join(lines) + "\n"


def measured_points(ds: Dataset) -> list[dict[str, Any]]:
    """The records' amplitudes with their noise std: one point per steady time record (max |x| of its
    harmonic series without the mean, from x and/or xdd, :func:`pyfmu_wrapper.solvers.harmonic.fuse`;
    its std the square root of the sum of the harmonics' variances) and one per FRC point (x_max, its
    std the one the diagnosis of ``ds`` uses: ``x_max_noise`` when the dataset states it, else the
    estimate of :meth:`.system.frc.FRCDiagnosis.run` -- the residual its best candidate leaves, with its
    degrees of freedom, guarded by a robust estimate). Each: ``record``, ``kind`` (steady, frc),
    ``omega``, ``force`` (as recorded), ``x``, ``sigma``."""
    from ..solvers.harmonic import fit_series, fuse, series_max

    out: list[dict[str, Any]] = []
    for r in ds.records:
        if r.kind != "time" or not r.omega:
            continue
        chans = {c: r[c] for c in ("x", "xdd") if r.has(c)}
        if not chans:
            continue
        s = fit_series(np.asarray(r["t"], float), chans, float(r.omega))
        X, vx = fuse(s, "x", "xdd" if "xdd" in chans else None, s.H)
        out.append(
            {
                "record": r.name,
                "kind": "steady",
                "omega": float(r.omega),
                "force": _record_force(r),
                "x": series_max(X),
                "sigma": float(math.sqrt(float(np.sum(vx[1:])))),
            }
        )
    if any(r.kind == "frc" for r in ds.records):
        from .system.frc import FRCDiagnosis

        sig = iter(FRCDiagnosis(ds).run().sigma)  # its points: the FRC records' rows, in order
        for r in ds.records:
            if r.kind != "frc":
                continue
            for w, F, x in zip(r["omega"], r["force_amplitude"], r["x_max"], strict=True):
                out.append(
                    {
                        "record": r.name,
                        "kind": "frc",
                        "omega": float(w),
                        "force": _round_force(float(F)),
                        "x": float(x),
                        "sigma": float(next(sig)),
                    }
                )
    return out


def read_curve(csv: Path, curve: str = "", column: str = "amplitude") -> dict[float, float]:
    """omega -> ``column`` of one curve (default: the first) of a run-scenario FRC CSV: ``amplitude``
    (the largest steady window's max |x|, as an FRC record's x_max is taken) or ``amplitude_periodic``
    (max |x - mean| of the harmonic series over the steady windows, as a steady record's point is;
    NaN where the CSV has no such column)."""
    import csv as _csv

    rows = list(_csv.DictReader(csv.open(encoding="utf-8")))
    curve = curve or rows[0]["curve"]
    return {float(r["omega"]): float(r.get(column) or "nan") for r in rows if r["curve"] == curve}


def read_scatter(csv: Path, curve: str = "") -> dict[float, float]:
    """omega -> the model amplitude's own scatter [m] of one curve (default: the first) of a
    run-scenario FRC CSV: half the spread of its steady windows' maxima (``change`` x amplitude / 2;
    ``change`` is that relative spread for an irregular point, the last relative change between
    windows for a converged one). A rattling play chain has no single steady amplitude: two samples
    of its motion (a record's periods, run-scenario's windows) differ by about this much."""
    import csv as _csv

    rows = list(_csv.DictReader(csv.open(encoding="utf-8")))
    curve = curve or rows[0]["curve"]
    out = {}
    for r in rows:
        if r["curve"] == curve:
            ch = float(r.get("change") or "nan")
            out[float(r["omega"])] = 0.5 * ch * abs(float(r["amplitude"])) if math.isfinite(ch) else 0.0
    return out


def chi2_per_point(
    points: list[dict[str, Any]],
    model: Mapping[float, Mapping[float, float]],
    scatter: Mapping[float, Mapping[float, float]] | None = None,
    periodic: Mapping[float, Mapping[float, float]] | None = None,
) -> dict[str, Any]:
    """chi2 / n of the records' ``points`` (:func:`measured_points`) against ``model`` (force as
    recorded -> omega -> amplitude, e.g. run-scenario's corrected curves), each residual in units of its
    point's noise -- with ``scatter`` (the same keys -> the model amplitude's std, :func:`read_scatter`)
    the point's noise and the model's scatter added in quadrature; also the worst point.

    ``periodic`` (the same keys -> the model's periodic amplitude, :func:`read_curve` of
    ``amplitude_periodic``): a steady point (the max |x - mean| of its record's harmonic series) is held
    against it where it is finite; an FRC point (x_max, the largest steady window's max |x|, as the
    generator's solver and a rig take it) against ``model``. The model scatter is added to both: the
    periodic part of a finite record of a rattling chain scatters too (10 periods of the noise-free
    play chain of seed 4242's records: 0.02-0.07 % from the long-run periodic amplitude; half the window
    spread, 0.002-0.04 % there, is a lower bound)."""
    z = []
    worst: dict[str, Any] = {}
    for p in points:
        curve = model[p["force"]]
        w = min(curve, key=lambda o: abs(o - p["omega"]))
        if abs(w - p["omega"]) > 1e-6 * p["omega"]:
            raise KeyError(f"no model amplitude at omega {p['omega']} (force {p['force']} N)")
        xm = curve[w]
        sm = float(scatter[p["force"]][w]) if scatter is not None else 0.0
        if periodic is not None and p["kind"] == "steady" and math.isfinite(periodic[p["force"]].get(w, math.nan)):
            xm = periodic[p["force"]][w]
        zi = (p["x"] - xm) / math.hypot(p["sigma"], sm)
        z.append(zi)
        if not worst or abs(zi) > abs(worst["z"]):
            worst = {**p, "model": xm, "model_scatter": sm, "z": float(zi)}
    za = np.asarray(z)
    return {"chi2_per_point": float(np.mean(za**2)), "n": int(za.size), "worst": worst}
