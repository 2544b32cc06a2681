"""The words and numbers of a run about its studies: :func:`study_summary` (the ``summary.json`` entry of a
study) and :func:`study_report` (the closing lines ``run-scenario`` prints: frequencies not converged or
irregular, the co-simulation's difference from the monolithic engine)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from ..models import MODELS
from ..physics.params import as_dict
from .runner import FRCData, MapData, PhaseData
from .sweeptable import engine_differences, irregular_mask, sweep_diagnostics

if TYPE_CHECKING:
    from .runner import FRCData, MapData, PhaseData

# --- summary -----------------------------------------------------------------------------------


def model_parameters(structure: Any, tmd: Any) -> dict[str, Any]:
    """The parameter blocks of the model that ran, each under its scenario key: the structure's (``base``,
    ``frame``, ``linear_tmd``, ...) and the paper's TMD only for a model that takes it."""
    unit = MODELS.of(structure)
    out = {unit.scenario_block or unit.name: as_dict(_resolved(structure))}
    if unit.takes_tmd:
        out["tmd"] = as_dict(tmd)
    return out


def _curve(c: Any, structure: Any) -> dict[str, Any]:
    """A curve's entry: its label and the parameters it ran with (the TMD's only where the model takes one)."""
    unit = MODELS.of(c.structure if c.structure is not None else structure)
    d: dict[str, Any] = dict(label=c.label, without_tmd=c.without_tmd)
    if unit.takes_tmd:
        d.update(tmd=as_dict(c.tmd), inertance_ratio=c.tmd.inertance_ratio)
    if c.structure is not None:
        d[unit.scenario_block or unit.name] = as_dict(_resolved(c.structure))
    att = attachment(c.structure if c.structure is not None else structure)
    if att is not None and unit.takes_tmd and not c.without_tmd:
        d["attachment"] = att
    return d


def _resolved(structure: Any) -> Any:
    """The structure with its defaults spelled out (a frame's top storey for 0, the TMD's own storey for
    -1), values the scenario's keys accept; a structure without such defaults as it is."""
    f = getattr(structure, "resolved", None)
    return f() if callable(f) else structure


def attachment(structure: Any) -> dict[str, Any] | None:
    """Where the TMD is attached on ``structure`` (a frame: ``storey``, ``inerter_to``, ``text``); None
    for a structure with one place for it (the paper's base)."""
    f = getattr(structure, "attachment", None)
    return f() if callable(f) else None


def response_body(structure: Any) -> str:
    """What the reported amplitude is the displacement of: the structure's own words, else the base."""
    return str(getattr(structure, "response_body", "the base"))


def study_summary(data: Any, structure: Any) -> dict[str, Any]:
    """The ``summary.json`` entry of a study run on ``structure`` (the scenario's primary structure)."""
    st = data.study
    d = dict(kind=st.kind, name=st.name, title=st.title, wall_time=data.wall_time)
    if isinstance(data, FRCData):
        d["omegas"] = _grid(st.omegas)
        d["curves"] = [_curve(c, structure) | dict(directions=data.peaks[c.label]) for c in st.curves]
    elif isinstance(data, MapData):
        d.update(
            parameter=st.parameter,
            values=_grid(st.values),
            omegas=_grid(st.omegas),
            amplitude_min=float(data.amplitude.min()),
            amplitude_max=float(data.amplitude.max()),
            **{k: v for k, v in sweep_diagnostics(data.table).items() if k != "method"},
            methods=sorted(set(data.table["method"])),
        )
        d["peak_per_value"] = [
            dict(value=float(v), peak_amplitude=float(row.max()), peak_omega=float(st.omegas[int(np.argmax(row))]))
            for v, row in zip(st.values, data.amplitude)
        ]
    else:
        d.update(n_periods=st.n_periods, samples_per_period=st.samples_per_period, portraits=[])
        for (w, label), ts in data.series.items():
            x, xd = ts.states[:, 0], ts.states[:, 1]
            d["portraits"].append(
                dict(
                    omega=w,
                    curve=label,
                    method=ts.method,
                    converged=ts.converged,
                    periods=ts.periods,
                    change=ts.change,
                    amplitude=ts.amplitude,
                    x_max=float(np.abs(x).max()),
                    xd_max=float(np.abs(xd).max()),
                )
            )
    return d


def _grid(a: Any) -> dict[str, Any]:
    a = np.asarray(a, float)
    return dict(start=float(a[0]), stop=float(a[-1]), count=int(a.size))


# --- summary.md ----------------------------------------------------------------------------------


def _num(x: Any, digits: int = 4) -> str:
    return "n/a" if x is None else f"{float(x):.{digits}g}"


def _seconds(x: Any) -> str:
    return "n/a" if x is None else f"{float(x):.3g} s"


def summary_markdown(summary: dict[str, Any], body: str = "the base") -> str:
    """``summary.md``: what ran and what came out, in a few lines (from summary.json's own numbers):
    per FRC curve its peak (amplitude of ``body`` and frequency, per sweep direction), the reduction
    against the study's curve without TMD, its attachment and convergence; per map the amplitude
    range; the timings."""
    sc = summary["scenario"]
    L = [f"# {sc['name']}", ""]
    if sc.get("description"):
        L += [str(sc["description"]).strip(), ""]
    L += [f"Engine: {summary['engine']}. Amplitude: max |x| of {body} [m], omega in rad/s.", ""]
    for st in summary["studies"]:
        L += [f"## {st['title']} ({st['kind']}, `{st['name']}`)", ""]
        if st["kind"] == "frc":
            ref = None
            for c in st["curves"]:
                if c.get("without_tmd"):
                    peaks = [d.get("peak_amplitude") for d in c["directions"].values()]
                    peaks = [p for p in peaks if p is not None]
                    ref = max(peaks) if peaks else None
                    break
            L += [
                "| curve | attachment | direction | peak [m] | at omega | reduction | not converged |",
                "|---|---|---|---|---|---|---|",
            ]
            for c in st["curves"]:
                att = (c.get("attachment") or {}).get("text", "-" if c.get("without_tmd") else "")
                for d, p in c["directions"].items():
                    a = p.get("peak_amplitude")
                    red = (
                        f"{100 * (1 - a / ref):.1f} %"
                        if (ref and a is not None and not c.get("without_tmd"))
                        else ("reference" if c.get("without_tmd") else "n/a")
                    )
                    nc = p.get("not_converged", 0)
                    irr = p.get("irregular", 0)
                    conv = f"{nc}" + (f" ({irr} irregular)" if irr else "")
                    L.append(
                        f"| {c['label']} | {att} | {d} | {_num(a)} | {_num(p.get('peak_omega'))} | {red} | {conv} |"
                    )
            L.append("")
        elif st["kind"] == "map":
            L += [
                f"{st['parameter']} over {st['values']['count']} values, {st['omegas']['count']} frequencies: "
                f"amplitude {_num(st['amplitude_min'])} to {_num(st['amplitude_max'])} m; "
                f"{st.get('not_converged', 0)} points not converged.",
                "",
            ]
        else:
            n = len(st.get("portraits", []))
            bad = sum(1 for p in st.get("portraits", []) if not p.get("converged", True))
            L += [f"{n} phase portraits, {bad} not converged.", ""]
    t = summary.get("timings", {})
    L += ["## Timings", "", f"- computing: {_seconds(t.get('compute'))}, in all: {_seconds(t.get('total'))}"]
    for name, w in (t.get("studies") or {}).items():
        L.append(f"- study {name}: {_seconds(w)}")
    co = t.get("cosim")
    if co:
        split = "" if not co.get("split_measured", True) else f" (inside the FMUs {_seconds(sum(co['fmus'].values()))})"
        L.append(f"- co-simulated points: {co['points']}, {_seconds(co['wall_time'])} of their own time{split}")
    L += ["", f"Code version {summary.get('code_version', '?')}, created {summary.get('created', '?')}.", ""]
    return "\n".join(L)


# --- closing report ------------------------------------------------------------------------------


def _w(x: float) -> str:
    return f"{float(x):g}"


def _pct(x: float) -> str:
    return "n/a" if x is None or not np.isfinite(x) else f"{100.0 * float(x):.3g} %"


def _points(rows: pd.DataFrame, limit: int = 12, with_value: bool = False) -> str:
    """'19.5, 20 rad/s', or for irregular points '20 rad/s (window scatter 67 %, not converged)'."""
    items = []
    for _, r in rows.head(limit).iterrows():
        s = _w(r["omega"])
        if with_value:
            s = f"({_w(r['value'])}, {s})"
        if bool(r.get("irregular", False)):
            notes = []
            if np.isfinite(float(r.get("change", np.nan))):
                notes.append(f"window scatter {_pct(r['change'])}")
            if not bool(r["converged"]):
                notes.append("not converged")
            s += " rad/s" + (f" ({', '.join(notes)})" if notes else "")
        items.append(s)
    more = f" and {len(rows) - limit} more" if len(rows) > limit else ""
    text = ", ".join(items) + more
    return text if text.endswith(")") or text.endswith("rad/s") else text + " rad/s"


def _flag_groups(t: pd.DataFrame) -> tuple[pd.DataFrame, pd.DataFrame, int]:
    """(regular points not converged, irregular points, number of points not converged in all)."""
    irr = t["irregular"].fillna(False).astype(bool) if "irregular" in t else pd.Series(False, index=t.index)
    conv = t["converged"].astype(bool)
    return t[~conv & ~irr], t[irr], int((~conv).sum())


def _reason_lines(name: str, t: Any, most: int = 3) -> list[str]:
    """Why points were reported not converged (the co-simulation's reasons), each distinct reason once
    with the frequencies it applies to; the full list is in summary.json and the CSV's reason column."""
    if "reason" not in t:
        return []
    by: dict[str, list[float]] = {}
    irr = t["irregular"].fillna(False).astype(bool) if "irregular" in t else [False] * len(t)
    for w, r, c, i in zip(t["omega"], t["reason"], t["converged"], irr):
        if not bool(c) and not i and isinstance(r, str) and r:  # (an irregular point's scatter is said already)
            by.setdefault(r, []).append(float(w))
    out = [
        f"{name}: not converged at {_w(min(ws))}" + (f"-{_w(max(ws))}" if len(ws) > 1 else "") + f" rad/s because {r}"
        for r, ws in list(by.items())[:most]
    ]
    if len(by) > most:
        out.append(f"{name}: ... {len(by) - most} more reasons in summary.json (not_converged_reasons)")
    return out


def study_report(data: Any) -> list[str]:
    """One line per study for the end of a run: which points did not converge or are irregular
    (and, for engine 'both', the difference over the regular points and the irregular ones apart)."""
    st = data.study
    lines = []
    if isinstance(data, PhaseData):
        bad = [f"{_w(w)} rad/s ({label})" for (w, label), ts in data.series.items() if not ts.converged]
        n = len(data.series)
        lines.append(
            f"{st.name}: all {n} phase portraits reached their steady state"
            if not bad
            else f"{st.name}: {len(bad)} of {n} phase portraits not converged: " + "; ".join(bad)
        )
        return lines
    t = data.table
    if isinstance(data, MapData):
        nc, irr, n_nc = _flag_groups(t)
        if not len(nc) and not len(irr):
            lines.append(f"{st.name}: all {len(t)} points converged and periodic")
        else:
            parts = []
            if len(nc):
                parts.append(f"not converged at ({st.parameter}, omega) = {_points(nc, with_value=True)}")
            if len(irr):
                parts.append(f"irregular at ({st.parameter}, omega) = {_points(irr, with_value=True)}")
            lines.append(
                f"{st.name}: {n_nc} of {len(t)} points not converged, {len(irr)} irregular: " + "; ".join(parts)
            )
        return lines
    parts, n_nc, n_irr = [], 0, 0
    for (label, d), td in t.groupby(["curve", "direction"], sort=False):
        nc, irr, k = _flag_groups(td)
        n_nc, n_irr = n_nc + k, n_irr + len(irr)
        sub = []
        if len(nc):
            sub.append(f"not converged at {_points(nc)}")
        if len(irr):
            sub.append(f"irregular at {_points(irr)}")
        if sub:
            parts.append(f'"{label}" ({d}): ' + ", ".join(sub))
    if not parts:
        lines.append(f"{st.name}: all {len(t)} points converged and periodic")
    else:
        lines.append(f"{st.name}: {n_nc} of {len(t)} points not converged, {n_irr} irregular: " + "; ".join(parts))
        lines += _reason_lines(st.name, t)
    diff = engine_differences(t)
    if diff:  # engine 'both': always one line, whatever the points are
        where = "" if diff["omega_max_difference"] is None else f" (at {_w(diff['omega_max_difference'])} rad/s)"
        line = (
            f"{st.name}: co-simulation against monolithic: max |difference| = {_pct(diff['max_abs_difference'])} "
            f"over the {diff['regular_points']} points both engines call regular{where}"
            if diff["regular_points"]
            else f"{st.name}: co-simulation against monolithic: no point both engines call regular"
        )
        if diff["not_converged_points"]:
            line += (
                f"; {diff['not_converged_points']} points the co-simulation reports not converged (not in that "
                f"maximum): max |difference| there {_pct(diff['max_abs_difference_not_converged'])}"
            )
        if diff["irregular_points"]:
            irr_t = t[irregular_mask(t)]
            items = []
            for (_, r), ip in zip(irr_t.iterrows(), diff["irregular_points"]):
                items.append(
                    f'{_w(ip["omega"])} rad/s "{r["curve"]}" ({r["direction"]}): difference '
                    f"{_pct(ip['difference'])}, window scatter {_pct(ip['scatter'])} co-simulation / "
                    f"{_pct(ip['reference_scatter'])} monolithic"
                )
            line += "; irregular points (not in that maximum): " + "; ".join(items)
        lines.append(line)
    return lines
