"""``score`` for the system suite: runs ``diagnose`` on every dataset and compares the verdict with
``manifest.json`` (docs/diagnose-evidence.md, "Check 1").

What is read from each diagnosis: ``verdict.effects`` (the effects named as causes),
``verdict.unexplained`` (a missing key counts as false), ``verdict.text`` (the printed verdict)
and ``verdict.parameters``. The printed text is checked against the flag: a text that says a gap
remains unexplained (``TEXT_UNEXPLAINED``) while the flag is false, or the reverse, is counted as a
disagreement.

Out-of-vocabulary datasets are classified as

* **honest**: ``unexplained`` is true (whatever effect is offered as a hint or named);
* **right**: the truth is invisible (chi-square of its noise-free difference from the nominal over
  all records below ``visible_chi2`` of the manifest) and the verdict names no effect;
* **confidently wrong**: an effect is named and ``unexplained`` is false;
* **missed**: a visible truth, no effect named, ``unexplained`` false ("no structural effect");
* **error**: diagnose refused the data or failed.
"""

from __future__ import annotations

import json
import re
import statistics
import time
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from collections.abc import Callable
    from pathlib import Path
    from typing import Any

TEXT_UNEXPLAINED = re.compile(
    r"unexplained|none of the candidates|not explained|remains unexplained|"
    r"structural gap remains",
    re.I,
)
TARGETS: dict[str, tuple[str, float]] = {  # what a field benchmark must reach (docs/diagnose-evidence.md)
    "singles_top1": (">=", 0.95),
    "clean_false_positive_rate": ("<=", 0.10),
    "pairs_both_named": (">=", 0.80),
    "oov_honest_or_right": (">=", 0.80),
    "oov_confidently_wrong": ("<=", 0.10),
    "unexplained_on_invocab_or_clean": ("<=", 0.05),
    "param_rel_error_median": ("<=", 0.05),
}


def verdict_of(res: dict) -> dict:
    """(effects, unexplained, text, parameters) of a diagnose result (system or FRC-only layout)."""
    v = res.get("verdict") or {}
    a = res.get("attribution") or {}
    effects = list(v.get("effects", a.get("effects", [])) or [])
    params = {}
    for k, p in (v.get("parameters") or {}).items():
        params[k] = p.get("value") if isinstance(p, dict) else p
    for k, p in (a.get("params") or {}).items():
        params.setdefault(k, p)
    text = str(v.get("text", a.get("verdict", "")))
    return {
        "effects": effects,
        "unexplained": bool(v.get("unexplained", False)),
        "text": text,
        "params": params,
        "unexplained_share": v.get("unexplained_share"),
    }


def oov_outcome(unexplained: bool, effects: list, visible: bool, error: bool = False) -> str:
    if error:
        return "error"
    if unexplained:
        return "honest"
    if effects:
        return "confidently_wrong"
    return "missed" if visible else "right"


def score_row(m: dict, res: dict | None, error: str | None = None) -> dict:
    cls = m.get("class") or ("clean" if not m["hidden"] else "single" if len(m["hidden"]) == 1 else "pair")
    hidden = list(m["hidden"])
    row = {"dataset": m["dataset"], "class": cls, "hidden": hidden, "error": error}
    if res is None:
        row.update(
            found=[],
            unexplained=False,
            text="",
            text_unexplained=False,
            correct=False,
            both_named=False,
            param_rel_error={},
        )
    else:
        v = verdict_of(res)
        row.update(
            found=v["effects"],
            unexplained=v["unexplained"],
            text=v["text"],
            text_unexplained=bool(TEXT_UNEXPLAINED.search(v["text"])),
            unexplained_share=v["unexplained_share"],
            correct=cls != "oov" and sorted(v["effects"]) == sorted(hidden),
            both_named=cls == "pair" and set(hidden) <= set(v["effects"]),
        )
        errs = {}
        for k, t in m.get("truth", {}).items():
            est = v["params"].get(k)
            if est is not None and t != 0 and k.split(".")[0] in v["effects"]:
                errs[k] = abs(float(est) - t) / abs(t)
        row["param_rel_error"] = errs
    row["text_flag_disagree"] = res is not None and row["text_unexplained"] != row["unexplained"]
    if cls == "oov":
        vis = bool(m.get("visibility", {}).get("visible", True))
        row["visible"] = vis
        row["oov_outcome"] = oov_outcome(row["unexplained"], row["found"], vis, res is None)
        row["correct"] = row["oov_outcome"] in ("honest", "right")  # an acceptable answer
    return row


def _rate(rows: list[Any], pred: Callable) -> float | None:
    return sum(1 for r in rows if pred(r)) / len(rows) if rows else None


def summarise(rows: list) -> dict:
    by = {c: [r for r in rows if r["class"] == c] for c in ("clean", "single", "pair", "oov")}
    invocab = by["clean"] + by["single"] + by["pair"]
    perr = [e for r in invocab for e in r["param_rel_error"].values()]
    oov = by["oov"]
    s: dict[str, Any] = {
        "n_datasets": len(rows),
        **{f"n_{c}": len(v) for c, v in by.items()},
        "singles_top1": _rate(by["single"], lambda r: r["correct"]),
        "clean_false_positive_rate": _rate(by["clean"], lambda r: bool(r["found"])),
        "pairs_both_named": _rate(by["pair"], lambda r: r["both_named"]),
        "pairs_exact": _rate(by["pair"], lambda r: r["correct"]),
        "oov_honest": _rate(oov, lambda r: r["oov_outcome"] == "honest"),
        "oov_right": _rate(oov, lambda r: r["oov_outcome"] == "right"),
        "oov_honest_or_right": _rate(oov, lambda r: r["oov_outcome"] in ("honest", "right")),
        "oov_confidently_wrong": _rate(oov, lambda r: r["oov_outcome"] == "confidently_wrong"),
        "oov_missed": _rate(oov, lambda r: r["oov_outcome"] == "missed"),
        "oov_invisible": sum(1 for r in oov if not r["visible"]),
        "unexplained_on_invocab_or_clean": _rate(invocab, lambda r: r["unexplained"]),
        "param_rel_error_median": statistics.median(perr) if perr else None,
        "text_flag_disagreements": sum(1 for r in rows if r["text_flag_disagree"]),
        "errors": sum(1 for r in rows if r["error"]),
        "median_seconds": statistics.median(r["seconds"] for r in rows) if rows else None,
        "max_seconds": max(r["seconds"] for r in rows) if rows else None,
    }
    per: dict[str, dict] = {}
    for r in by["single"] + by["pair"]:
        for e in r["hidden"]:
            d = per.setdefault(e, {"n": 0, "named": 0, "n_single": 0, "single_top1": 0, "errors": []})
            d["n"] += 1
            d["named"] += int(e in r["found"])
            d["n_single"] += int(r["class"] == "single")
            d["single_top1"] += int(r["class"] == "single" and r["correct"])
            d["errors"] += [v for k, v in r["param_rel_error"].items() if k.split(".")[0] == e]
    s["per_effect"] = {
        e: {
            "n": d["n"],
            "named": d["named"],
            "n_single": d["n_single"],
            "single_top1": d["single_top1"],
            "param_rel_error_median": statistics.median(d["errors"]) if d["errors"] else None,
        }
        for e, d in sorted(per.items())
    }
    po: dict[str, dict] = {}
    for r in oov:
        e = r["hidden"][0] if r["hidden"] else "?"
        d = po.setdefault(e, {"n": 0, "honest": 0, "right": 0, "confidently_wrong": 0, "missed": 0, "error": 0})
        d["n"] += 1
        d[r["oov_outcome"]] += 1
    s["per_oov_effect"] = dict(sorted(po.items()))
    s["targets"] = {
        k: {
            "target": f"{op} {lim:g}",
            "value": s[k],
            "met": s[k] is not None and (s[k] >= lim if op == ">=" else s[k] <= lim),
        }
        for k, (op, lim) in TARGETS.items()
    }
    return s


def is_system_suite(bench: Path) -> bool:
    """True when ``bench/manifest.json`` says it is the system suite (False when unreadable)."""
    try:
        return json.loads((Path(bench) / "manifest.json").read_text()).get("suite") == "system"
    except (OSError, ValueError, AttributeError):
        return False


def score_system(bench: Path, results: dict | None = None, progress: Callable[..., Any] | None = None) -> dict:
    """Diagnose every dataset of a system-suite folder (or take ``results[name]``) and score it."""
    from ..data import DataError
    from ..run import run_diagnosis

    bench = Path(bench)
    man = json.loads((bench / "manifest.json").read_text())
    rows = []
    for m in man["datasets"]:
        t0 = time.perf_counter()
        res, err = None, None
        try:
            res = results[m["dataset"]] if results is not None else run_diagnosis(bench / m["dataset"], out=None)
        except DataError as e:
            err = f"bad data: {e}"
        except Exception as e:  # a failed diagnosis is scored as a failure, the rest still runs
            err = f"{type(e).__name__}: {e}"
        row = score_row(m, res, err)
        row["record_kind"] = m.get("record_kind", "steady")
        row["seconds"] = time.perf_counter() - t0
        rows.append(row)
        if progress:
            progress(row)
    summary = summarise(rows)
    kinds = sorted({r["record_kind"] for r in rows})
    summary["by_record_kind"] = {k: summarise([r for r in rows if r["record_kind"] == k]) for k in kinds}
    return {"suite": "system", "written_by": "score", "summary": summary, "rows": rows}


def _pct(x: float | None) -> str:
    return "-" if x is None else f"{100 * x:.0f} %"


def table(summary: dict) -> str:
    """The score as a Markdown table (the one in docs/diagnose-evidence.md)."""
    s = summary
    n = {c: s[f"n_{c}"] for c in ("clean", "single", "pair", "oov")}
    lines = [
        f"{s['n_datasets']} datasets: {n['clean']} clean, {n['single']} singles, {n['pair']} pairs, "
        f"{n['oov']} out of vocabulary ({s['oov_invisible']} of them invisible)",
        "",
        "| measure | value | target | met |",
        "|---|---|---|---|",
    ]

    def add(name: str, key: str, frac: str) -> None:
        t = s["targets"].get(key)
        lines.append(
            f"| {name} | {frac} ({_pct(s[key])}) | {t['target'] if t else ''} | "
            f"{'yes' if t and t['met'] else ('no' if t else '')} |"
        )

    def cnt(c: str, pred_rate: str) -> str:
        return f"{round((s[pred_rate] or 0) * n[c])}/{n[c]}"

    add("singles: top-1 (the named set is the hidden one)", "singles_top1", cnt("single", "singles_top1"))
    add("clean: a false effect named", "clean_false_positive_rate", cnt("clean", "clean_false_positive_rate"))
    add("pairs: both effects named", "pairs_both_named", cnt("pair", "pairs_both_named"))
    add("OOV: honest (unexplained) or right", "oov_honest_or_right", cnt("oov", "oov_honest_or_right"))
    add("OOV: confidently wrong", "oov_confidently_wrong", cnt("oov", "oov_confidently_wrong"))
    ni = n["clean"] + n["single"] + n["pair"]
    u = s["unexplained_on_invocab_or_clean"]
    add(
        "unexplained raised on in-vocabulary or clean",
        "unexplained_on_invocab_or_clean",
        f"{round((u or 0) * ni)}/{ni}",
    )
    pe = s["param_rel_error_median"]
    lines.append(
        f"| median parameter error (named hidden effects) | {'-' if pe is None else f'{100 * pe:.2f} %'} | "
        f"<= 5 % | {'yes' if s['targets']['param_rel_error_median']['met'] else 'no'} |"
    )
    lines.append(
        f"| OOV honest / right / confidently wrong / missed / invisible | "
        f"{_pct(s['oov_honest'])} / {_pct(s['oov_right'])} / {_pct(s['oov_confidently_wrong'])} / "
        f"{_pct(s['oov_missed'])} / {s['oov_invisible']} | | |"
    )
    lines.append(f"| verdict text and `unexplained` flag disagree | {s['text_flag_disagreements']} | | |")
    lines.append(f"| diagnose refused or failed | {s['errors']} | | |")
    lines += ["", "| effect | singles: top-1 | singles + pairs: named | param. error median |", "|---|---|---|---|"]
    for e, d in s["per_effect"].items():
        pe = d["param_rel_error_median"]
        lines.append(
            f"| {e} | {d['single_top1']}/{d['n_single']} | {d['named']}/{d['n']} | "
            f"{'-' if pe is None else f'{100 * pe:.2f} %'} |"
        )
    lines += [
        "",
        "| OOV effect | datasets | honest | right | confidently wrong | missed | error |",
        "|---|---|---|---|---|---|---|",
    ]
    for e, d in s["per_oov_effect"].items():
        lines.append(
            f"| {e} | {d['n']} | {d['honest']} | {d['right']} | {d['confidently_wrong']} | "
            f"{d['missed']} | {d['error']} |"
        )
    return "\n".join(lines)


def row_line(r: dict) -> str:
    """One progress line (printed by score; labels may be shown here: score reads the manifest)."""
    if r["class"] == "oov":
        st = r["oov_outcome"]
    elif r["class"] == "pair":
        st = "both named" if r["both_named"] else "MISSED"
    else:
        st = "ok" if r["correct"] else "WRONG"
    un = " unexplained" if r["unexplained"] else ""
    err = f" ({r['error']})" if r["error"] else ""
    return (
        f"{r['dataset']} [{r['class']}]: hidden {r['hidden'] or '-'} found {r['found'] or '-'}{un} {st}"
        f"{err} ({r['seconds']:.1f} s)"
    )


def score_line(r: dict) -> str:
    """The progress line of ``score`` for a row of either suite."""
    if "class" in r:
        return row_line(r)
    return f"{r['dataset']}: hidden {r['hidden'] or '-'} found {r['found'] or '-'} {'ok' if r['correct'] else 'WRONG'}"


def score_summary(res: dict) -> str:
    """What ``score`` prints at the end: the table (system suite) or the summary as JSON (link suite)."""
    if res.get("suite") == "system":
        return tables(res["summary"])
    return json.dumps(res["summary"], indent=1)


def tables(summary: dict) -> str:
    """The table of every record kind apart (transient, steady), or the one table."""
    by = summary.get("by_record_kind") or {}
    if len(by) <= 1:
        return table(summary)
    return "\n\n".join(f"### {k} records\n\n" + table(s) for k, s in by.items())
