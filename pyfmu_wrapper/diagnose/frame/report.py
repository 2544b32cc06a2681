"""Run the frame diagnosis of a dataset and write its report: diagnosis.json (the contract's verdict
keys: effects, elements, parameters, ambiguous, unexplained, text), report.md and where.png (the frame
with the named elements marked)."""

from __future__ import annotations

import json
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from pathlib import Path

    from ..data import Dataset


def run_frame(ds: Dataset, out: Path | None) -> dict[str, Any]:
    """Diagnose the frame dataset ``ds``; write the report to ``out`` when given."""
    from .. import progress
    from .fit import FrameDiagnosis

    fd = FrameDiagnosis(ds)
    fr = fd.run()
    v = fr.pop("verdict")
    v["sources"] = {"transient_records": [r.name for r in ds.records]}
    v["disagreements"] = []
    res: dict[str, Any] = {
        "schema": "pyfmu-diagnose/2",
        "dataset": str(ds.path),
        "level": "system",
        "kind": "frame",
        "verdict": v,
        "frame": fr,
    }
    if out is not None:
        progress.stage("writing the report")
        write(res, ds, out)
    return res


def write(res: dict[str, Any], ds: Dataset, out: Path) -> None:
    from ..system.transient_report import json_default

    out.mkdir(parents=True, exist_ok=True)
    (out / "diagnosis.json").write_text(json.dumps(res, indent=1, default=json_default))
    plot_frame(ds.nominal, res["verdict"], out / "where.png")
    v, f = res["verdict"], res["frame"]
    L = [
        f"# Diagnosis of {res['dataset']} (a {f['model']['storeys']}-storey frame, transient records)",
        "",
        f"**{v['text']}**",
        "",
        f"chi-square {v['chi2_before']:.6g} (nominal) -> {v['chi2_after']:.6g} on {v['dof']} degrees of freedom; "
        f"CPU {f['cpu_s']:.1f} s.",
        "",
        "![where](where.png)",
        "",
    ]
    if v["parameters"]:
        L += ["| parameter | value | std | unit |", "|---|---|---|---|"]
        L += [f"| {k} | {p['value']:.6g} | {p['std']:.2g} | {p['unit']} |" for k, p in v["parameters"].items()]
        L.append("")
    if v["ambiguous"]:
        L += ["Equally good alternatives (within the noise):", ""]
        L += [
            f"- {' + '.join(f'{e} at {el}' for e, el in zip(a['effects'], a['elements'], strict=True))}"
            for a in v["ambiguous"]
        ]
        L.append("")
    L += ["## Where the residual lives", "", f["where"]["text"], "", "## Candidates", ""]
    L += ["| effects | chi2/dof | parameters |", "|---|---|---|"]
    for c in f["candidates"]:
        ps = "; ".join(f"{k} = {p['value']:.4g} +- {p['std']:.2g}" for k, p in c["params"].items())
        L.append(
            f"| {' + '.join(f'{e} at {el}' for e, el in zip(c['effects'], c['elements'], strict=True))} | {c['chi2_per_dof']:.4g} | {ps} |"
        )
    L += [
        "",
        "## Records",
        "",
        "| record | samples | rate [Hz] | start state fitted | noise std |",
        "|---|---|---|---|---|",
    ]
    noise = {n["record"]: n["noise_std"] for n in f["noise"]}
    for r in f["records"]:
        ns = ", ".join(f"{k} {s:.3g}" for k, s in noise[r["record"]].items())
        L.append(
            f"| {r['record']} | {r['samples']} | {r['rate_hz']:.4g} | {'yes' if r['start_fitted'] else 'no'} | {ns} |"
        )
    if v.get("not_tried"):
        L += ["", "Not tried (CPU budget): " + "; ".join(v["not_tried"])]
    (out / "report.md").write_text("\n".join(L) + "\n", encoding="utf-8")


def plot_frame(nominal: dict[str, Any], verdict: dict[str, Any], path: Path) -> None:
    """The frame as stacked storeys with the TMD beside its storey; the named elements in red, the
    ambiguous alternatives in orange, the measured channels' storeys unmarked."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Rectangle

    n = int(nominal["frame"]["storeys"])
    s = int(nominal["tmd"]["storey"])
    to = int(nominal["tmd"]["inerter_to"])
    named = list(zip(verdict.get("effects", []), verdict.get("elements", []), strict=False))
    alt = [(e, el) for a in verdict.get("ambiguous", []) for e, el in zip(a["effects"], a["elements"], strict=False)]

    def colour(element: str, part: str = "") -> str:
        """Red: named there; orange: an ambiguous alternative there (``part``: the storey's slab, its
        mass, or its columns, stiffness and damping)."""
        for pool, c in ((named, "tab:red"), (alt, "tab:orange")):
            for e, el in pool:
                if el == element and (not part or (e == "storey_mass") == (part == "slab")):
                    return c
        return "0.8"

    fig, ax = plt.subplots(figsize=(5.5, 1.2 * n + 2))
    ax.plot([-1.5, 1.5], [0, 0], color="k", lw=3)
    for i in range(1, n + 1):
        y = 1.2 * i
        ax.add_patch(Rectangle((-1.0, y - 0.15), 2.0, 0.3, color=colour(f"storey {i}", "slab")))
        c = colour(f"storey {i}", "columns")
        for xx in (-0.9, 0.9):
            ax.plot([xx, xx], [y - 1.05, y - 0.15], color=c if c != "0.8" else "k", lw=3 if c != "0.8" else 2)
        what = [e for e, el in named if el == f"storey {i}"] + [f"{e} (or)" for e, el in alt if el == f"storey {i}"]
        ax.text(1.1, y, f"storey {i}" + (f": {', '.join(what)}" if what else ""), va="center", fontsize=8)
    ys = 1.2 * s
    ax.add_patch(Rectangle((-2.6, ys + 0.25), 0.6, 0.45, color=colour("tmd")))
    ax.plot([-2.0, -1.0], [ys + 0.47, ys], color=colour("tmd link") if colour("tmd link") != "0.8" else "k", lw=2)
    yt = 1.2 * to if to > 0 else 0.0
    ax.plot(
        [-2.3, -2.3, -1.0],
        [ys + 0.25, yt, yt],
        ls="--",
        color=colour("tmd link") if colour("tmd link") != "0.8" else "0.4",
    )
    tm = [e for e, el in named if el in ("tmd", "tmd link")] + [
        f"{e} (or)" for e, el in alt if el in ("tmd", "tmd link")
    ]
    ax.text(-2.9, ys + 0.85, "TMD" + (f": {', '.join(tm)}" if tm else ""), fontsize=8)
    meas = [f"{e} at {el}" for e, el in named if el.startswith("channel") or el == "force"]
    title = "named: " + (", ".join(f"{e} at {el}" for e, el in named) if named else "nothing")
    ax.set_title(title + ("  (unexplained)" if verdict.get("unexplained") else ""), fontsize=9)
    if meas:
        ax.text(-2.9, -0.5, "measurement: " + ", ".join(meas), fontsize=8, color="tab:red")
    ax.set_xlim(-3.2, 3.6)
    ax.set_ylim(-0.8, 1.2 * n + 1.3)
    ax.set_axis_off()
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
