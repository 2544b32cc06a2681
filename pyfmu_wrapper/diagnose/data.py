"""Measured datasets for ``diagnose``: a folder with ``dataset.yaml`` and CSV files (SI units); the
CSV records themselves are read by :mod:`.records`.

Record kinds (told apart by their columns):

* ``link``   -- ``t, displacement, force`` (optional ``velocity``, ``acceleration``): relative motion
  across one device and the force through it (damper test rig).
* ``time``   -- system level: ``t, force`` and the displacements ``x, y`` or the accelerations
  ``xdd, ydd`` (or both; optional ``xd, yd``): base plus TMD under the harmonic force ``force``.
* ``frc``    -- system level stepped sine: ``omega, force_amplitude, x_max`` (optional ``direction``).

Every problem is raised as :class:`DataError` naming the file, and where it applies the row
(1-based data row, not counting the header or '#' comment lines) and the column.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import yaml

from .errors import DataError
from .records import REQUIRED, check_header, data_error, read_record, say, storey_columns

if TYPE_CHECKING:
    from collections.abc import Callable
    from pathlib import Path
    from typing import Any


LINK_NOMINAL = ("stiffness", "damping", "friction_force", "friction_slope", "inertance")


@dataclass
class Dataset:
    path: Path
    level: str  #: link | system
    nominal: dict  #: link: force-law parameters; system: {"base": {...}, "tmd": {...}}
    records: list
    description: str = ""
    raw: dict = field(default_factory=dict)
    acquisition: dict = field(default_factory=dict)  #: channel -> acquisition.Chain (dataset.yaml 'acquisition')


#: keys allowed in dataset.yaml (top level) and in each entry of ``records``; anything else is
#: refused with this list (a typo such as ``rol: test`` must not be ignored silently).
ALLOWED_KEYS = {
    "dataset": ("level", "description", "nominal", "records", "x_max_noise", "acquisition"),
    "record": (
        "file",
        "kind",
        "omega",
        "frequency_hz",
        "force_amplitude",
        "amplitude",
        "role",
        "source_file",
        "description",
        "free_decay",
    ),
}


def _line(node: Any, key: int | str) -> int | None:
    f = getattr(node, "line_of", None)
    return f(key) if f is not None else None


def _number(
    v: Any,
    file: Path | str,
    key: str,
    line: int | None = None,
    minimum: float | None = None,
    strict: bool = False,
    unit: str = "",
) -> float:
    try:
        if isinstance(v, bool):
            raise TypeError
        x = float(v)
    except (TypeError, ValueError):
        raise data_error(file, f"'{key}' must be a number, got {v!r}", line=line) from None
    if not math.isfinite(x):
        raise data_error(file, f"'{key}' must be finite, got {v!r}", line=line)
    if minimum is not None and (x <= minimum if strict else x < minimum):
        raise data_error(
            file,
            f"'{key}' must be {'>' if strict else '>='} {minimum:g}{' ' + unit if unit else ''} "
            f"(a physical value), got {v!r}",
            line=line,
        )
    return x


def _unknown_keys(
    node: Any,
    allowed: tuple[str, ...],
    file: Path,
    where: str,
) -> None:
    unknown = [k for k in node if k not in allowed]
    if unknown:
        k = unknown[0]
        raise data_error(
            file,
            f"{where}: unknown key(s) {[str(u) for u in unknown]}; allowed keys: {list(allowed)}",
            line=_line(node, k),
        )


def _plain_data(x: Any) -> Any:
    """MarkedDict/MarkedList (with line numbers) -> plain dict/list."""
    if isinstance(x, dict):
        return {k: _plain_data(v) for k, v in x.items()}
    if isinstance(x, list):
        return [_plain_data(v) for v in x]
    return x


def load_dataset(
    path: Path | str, model_override: dict | None = None, log: Callable = say, model_source: str | None = None
) -> Dataset:
    """Load and validate ``path/dataset.yaml`` and its records (``model_override``: a nominal model
    read from the file ``model_source``). Progress of long records goes to ``log``."""
    from ..errors import read_utf8
    from ..inputs.yamlio import load_marked

    path = Path(path)
    yml = path if path.suffix in (".yaml", ".yml") else path / "dataset.yaml"
    path = yml.parent
    if not yml.is_file():
        raise data_error(yml, "file not found (a dataset is a folder with dataset.yaml and CSV files)")
    text = read_utf8(yml, error=DataError)
    try:
        raw = load_marked(text, name=str(yml))
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None) or getattr(e, "context_mark", None)
        raise data_error(
            yml, f"invalid YAML: {' '.join(str(e).split())}", line=None if mark is None else mark.line + 1
        ) from None
    raw = {} if raw is None else raw
    if not isinstance(raw, dict):
        raise data_error(yml, "must be a mapping with keys level, nominal, records")
    _unknown_keys(raw, ALLOWED_KEYS["dataset"], yml, "dataset.yaml")
    level = raw.get("level", "system")
    if level not in ("link", "system"):
        raise data_error(yml, f"'level' must be 'link' or 'system', got {level!r}", line=_line(raw, "level"))
    if "x_max_noise" in raw:
        raw["x_max_noise"] = _number(raw["x_max_noise"], yml, "x_max_noise", _line(raw, "x_max_noise"), 0.0, unit="m")
    nominal = model_override if model_override is not None else raw.get("nominal")
    if not isinstance(nominal, dict):
        raise data_error(
            yml, "'nominal' (the model parameters) is missing or not a mapping", line=_line(raw, "nominal")
        )
    nominal = normalise_nominal(nominal, level, yml if model_override is None else (model_source or "--model"))
    entries = raw.get("records")
    if not isinstance(entries, list) or not entries:
        raise data_error(yml, "'records' must be a non-empty list of {file: ..., ...}", line=_line(raw, "records"))
    records = []
    todo: list[tuple[Path, dict]] = []
    seen: dict[Path, int] = {}
    for i, entry in enumerate(entries):
        ln = _line(entries, i)
        if isinstance(entry, str):
            entry = {"file": entry}
        if not isinstance(entry, dict) or "file" not in entry:
            raise data_error(yml, f"records[{i}] needs a 'file' key (a CSV file name)", line=ln)
        _unknown_keys(entry, ALLOWED_KEYS["record"], yml, f"records[{i}] ({entry.get('file')})")
        if not isinstance(entry["file"], str) or not entry["file"].strip():
            raise data_error(
                yml, f"records[{i}].file must be a file name, got {entry['file']!r}", line=_line(entry, "file") or ln
            )
        for key in ("omega", "force_amplitude", "amplitude", "frequency_hz"):
            if key in entry:
                entry[key] = _number(
                    entry[key],
                    yml,
                    f"records[{i}].{key}",
                    _line(entry, key) or ln,
                    0.0,
                    strict=True,
                    unit={"omega": "rad/s", "frequency_hz": "Hz"}.get(key, ""),
                )
        if entry.get("role") not in (None, "train", "test"):
            raise data_error(
                yml,
                f"records[{i}].role must be 'train' or 'test', got {entry['role']!r}",
                line=_line(entry, "role") or ln,
            )
        if entry.get("kind") not in (None, "decay", *REQUIRED):
            raise data_error(
                yml,
                f"records[{i}].kind must be one of {[*REQUIRED, 'decay']}, got {entry['kind']!r}",
                line=_line(entry, "kind") or ln,
            )
        if "free_decay" in entry and not isinstance(entry["free_decay"], bool):
            raise data_error(
                yml,
                f"records[{i}].free_decay must be true or false, got {entry['free_decay']!r}",
                line=_line(entry, "free_decay") or ln,
            )
        if entry.get("kind") == "decay":  # a free decay: a transient record without force, said so
            if entry.get("free_decay") is False:
                raise data_error(yml, f"records[{i}]: kind: decay and free_decay: false contradict each other", line=ln)
            entry["kind"], entry["free_decay"] = "transient", True
        real = (path / entry["file"]).resolve()
        if real in seen:
            raise data_error(
                yml,
                f"records[{i}] ({entry['file']}) is the same file as records[{seen[real]}]: a record listed "
                "twice could be both fitted and held out; list each record once",
                line=_line(entry, "file") or ln,
            )
        seen[real] = i
        todo.append((path / entry["file"], _plain_data(entry)))
    for file, entry in todo:  # every record's file and header before any is read
        if not file.is_file():
            raise data_error(file, "file not found")
        check_header(file, level, entry)
    for file, entry in todo:
        records.append(read_record(file, level, entry, log=log))
    roles = [r.role for r in records if r.kind != "frc"]
    if any(roles) and "test" not in roles:
        raise data_error(
            yml,
            "every record has role 'train': mark at least one record 'role: test' (held out), or give "
            "no roles (records are then held out automatically)",
            line=_line(raw, "records"),
        )
    if roles and all(r == "test" for r in roles):
        raise data_error(
            yml, "every record has role 'test': at least one record must be for training", line=_line(raw, "records")
        )
    if level == "system":
        check_frame_records(records, nominal, yml)
        check_time_base(records, nominal, yml)
    from .acquisition import check_records, correct_frc, parse_acquisition

    extra = sorted({c for r in records for c in storey_columns(r.columns)}) if "frame" in nominal else ()
    acq = parse_acquisition(raw.get("acquisition"), yml, level, extra_channels=tuple(extra))
    check_records(acq, records, yml)
    correct_frc(records, acq)
    return Dataset(
        path=path,
        level=level,
        nominal=nominal,
        records=records,
        description=str(raw.get("description", "")),
        raw=_plain_data(raw),
        acquisition=acq,
    )


def normalise_nominal(nom: dict, level: str, file: Path | str) -> dict:
    """Link: {stiffness, damping, friction_force, friction_slope, inertance} (missing = 0, slope 1e3),
    each within the physics registry's bounds (k, c, df, I >= 0; s > 0).
    System: {"base": BaseParams kwargs, "tmd": TMDParams kwargs} (validated by the physics classes)."""
    from ..physics import registry
    from ..physics.params import BaseParams, ParameterError, TMDParams, field_names

    if "nominal" in nom and isinstance(nom["nominal"], dict):
        nom = nom["nominal"]
    if level == "system" and "frame" in nom:
        return normalise_frame_nominal(nom, file)
    ln = lambda node, k: _line(node, k) or _line(nom, k)  # noqa: E731
    if level == "link":
        if "link" in nom and set(nom) - {"link", "base", "tmd"}:
            extra = sorted(map(str, set(nom) - {"link", "base", "tmd"}))
            raise data_error(
                file,
                f"nominal: unknown key(s) {extra} beside 'link'; allowed keys: ['link'] (or the link "
                f"parameters {list(LINK_NOMINAL)} directly)",
                line=_line(nom, extra[0]),
            )
        src = nom.get("link", nom)
        if "tmd" in nom and "link" not in nom:  # a scenario: its TMD link is the device
            try:
                t = TMDParams(**nom["tmd"], source=str(file))
            except (ParameterError, TypeError) as e:
                raise data_error(file, f"nominal model: {e}", line=_line(nom, "tmd")) from None
            src = {
                "stiffness": t.stiffness,
                "damping": t.damping,
                "friction_force": t.friction_force,
                "friction_slope": t.friction_slope,
                "inertance": t.inertance,
            }
        if not isinstance(src, dict):
            raise data_error(file, "nominal.link must be a mapping of the link parameters", line=_line(nom, "link"))
        unknown = set(src) - set(LINK_NOMINAL)
        if unknown:
            raise data_error(
                file,
                f"unknown nominal link parameter(s) {sorted(map(str, unknown))}; known: {list(LINK_NOMINAL)}",
                line=ln(src, sorted(map(str, unknown))[0]),
            )
        out = {}
        for k in LINK_NOMINAL:
            par = registry.get("tmd", k)
            out[k] = _number(
                src.get(k, 1e3 if k == "friction_slope" else 0.0),
                file,
                f"nominal.{k}",
                ln(src, k),
                par.minimum,
                par.strict,
                par.unit,
            )
        return out
    extra = [k for k in nom if k not in ("base", "tmd")]
    if "base" not in nom or "tmd" not in nom:
        raise data_error(file, "a system-level nominal model needs 'base' and 'tmd' mappings", line=_line(nom, "base"))
    if extra:
        raise data_error(
            file,
            f"nominal: unknown key(s) {[str(k) for k in extra]}; allowed keys: ['base', 'tmd']",
            line=_line(nom, extra[0]),
        )
    for part, cls in (("base", BaseParams), ("tmd", TMDParams)):
        node = nom[part]
        if not isinstance(node, dict):
            raise data_error(file, f"nominal.{part} must be a mapping, got {node!r}", line=_line(nom, part))
        allowed = [f for f in field_names(cls) if f != "source"]
        bad = [k for k in node if k not in allowed]
        if bad:
            raise data_error(
                file,
                f"nominal.{part}: unknown key(s) {[str(k) for k in bad]}; allowed keys: {allowed}",
                line=ln(node, bad[0]),
            )
        try:
            cls(**node, source=str(file))
        except (ParameterError, TypeError) as e:
            msg = str(e).replace(f" (from {file})", "")
            raise data_error(file, f"nominal model: {part}: {msg}", line=_line(nom, part)) from None
    return {"base": _plain_data(nom["base"]), "tmd": _plain_data(nom["tmd"])}


#: keys of a dataset's nominal frame: block (mass, stiffness, damping: one number, or a list of one per storey)
FRAME_KEYS = ("storeys", "mass", "stiffness", "damping", "force_storey", "force_amplitude")
#: the TMD's attachment keys in a frame nominal's tmd: block (beside the TMDParams fields)
FRAME_TMD_KEYS = ("storey", "inerter_to")


def _storey_int(v: Any, file: Path | str, key: str, line: int | None, lo: int, hi: int) -> int:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or v != int(v) or not lo <= int(v) <= hi:
        raise data_error(file, f"'{key}' must be an integer {lo}..{hi}, got {v!r}", line=line)
    return int(v)


def normalise_frame_nominal(nom: dict, file: Path | str) -> dict:
    """A frame nominal ``{frame: {storeys, mass, stiffness, damping, force_storey}, tmd: {..., storey,
    inerter_to}}`` (mass/stiffness/damping one number or one per storey, storey 1 first), validated with
    located errors (the key, the list entry, the line), as ``{"frame": {storeys, mass, stiffness,
    damping (lists), force_storey}, "tmd": {TMDParams fields, storey, inerter_to}}``."""
    from ..physics.params import ParameterError, TMDParams, field_names

    extra = [k for k in nom if k not in ("frame", "tmd")]
    if extra:
        raise data_error(
            file,
            f"nominal: unknown key(s) {[str(k) for k in extra]}; a frame nominal has keys ['frame', 'tmd']",
            line=_line(nom, extra[0]),
        )
    fr = nom["frame"]
    if not isinstance(fr, dict):
        raise data_error(file, f"nominal.frame must be a mapping, got {fr!r}", line=_line(nom, "frame"))
    bad = [k for k in fr if k not in FRAME_KEYS]
    if bad:
        raise data_error(
            file,
            f"nominal.frame: unknown key(s) {[str(k) for k in bad]}; allowed keys: {list(FRAME_KEYS)}",
            line=_line(fr, bad[0]) or _line(nom, "frame"),
        )
    ln = lambda k: _line(fr, k) or _line(nom, "frame")  # noqa: E731
    for k in ("storeys", "mass", "stiffness", "damping"):
        if k not in fr:
            raise data_error(file, f"nominal.frame.{k} is missing (a frame needs {FRAME_KEYS[:4]})", line=ln("storeys"))
    n = _storey_int(fr["storeys"], file, "nominal.frame.storeys", ln("storeys"), 1, 20)
    out: dict[str, Any] = {"storeys": n}
    for k, strict in (("mass", True), ("stiffness", True), ("damping", False)):
        v = fr[k]
        if isinstance(v, list):
            if len(v) != n:
                raise data_error(
                    file,
                    f"'nominal.frame.{k}' must be one number or a list of one per storey ({n}, storey 1 first), "
                    f"got a list of {len(v)}",
                    line=ln(k),
                )
            out[k] = [
                _number(x, file, f"nominal.frame.{k}[{i}] (storey {i + 1})", _line(v, i) or ln(k), 0.0, strict)
                for i, x in enumerate(v)
            ]
        else:
            out[k] = [_number(v, file, f"nominal.frame.{k}", ln(k), 0.0, strict)] * n
    out["force_storey"] = _storey_int(
        fr.get("force_storey", n), file, "nominal.frame.force_storey", ln("force_storey"), 1, n
    )
    if "force_amplitude" in fr:
        out["force_amplitude"] = _number(
            fr["force_amplitude"], file, "nominal.frame.force_amplitude", ln("force_amplitude")
        )
    td = nom.get("tmd")
    if not isinstance(td, dict):
        raise data_error(file, "a frame nominal needs a 'tmd' mapping (the TMD's parameters)", line=_line(nom, "tmd"))
    allowed = [f for f in field_names(TMDParams) if f != "source"] + list(FRAME_TMD_KEYS)
    bad = [k for k in td if k not in allowed]
    if bad:
        raise data_error(
            file,
            f"nominal.tmd: unknown key(s) {[str(k) for k in bad]}; allowed keys: {allowed}",
            line=_line(td, bad[0]) or _line(nom, "tmd"),
        )
    tln = lambda k: _line(td, k) or _line(nom, "tmd")  # noqa: E731
    tmd = {k: _plain_data(v) for k, v in td.items() if k not in FRAME_TMD_KEYS}
    try:
        TMDParams(**tmd, source=str(file))
    except (ParameterError, TypeError) as e:
        msg = str(e).replace(f" (from {file})", "")
        raise data_error(file, f"nominal model: tmd: {msg}", line=_line(nom, "tmd")) from None
    s = _storey_int(td.get("storey", n), file, "nominal.tmd.storey", tln("storey"), 1, n)
    j = _storey_int(td.get("inerter_to", s), file, "nominal.tmd.inerter_to", tln("inerter_to"), 0, n)
    return {"frame": out, "tmd": {**tmd, "storey": s, "inerter_to": j}}


def nominal_modes_hz(nominal: dict) -> list[float]:
    """The undamped natural frequencies [Hz] of a system-level nominal model (base + TMD, the inerter
    taken as ideal between them, the cubic spring and the play left out): the roots of
    det(K - w^2 M) = 0 with M = [[M + I, -I], [-I, m + I]], K = [[K + k, -k], [-k, k]]."""
    import numpy as np

    from ..physics.params import BaseParams, InerterModel, TMDParams

    if "frame" in nominal:
        from .frame.model import FrameModel

        return FrameModel.from_nominal(nominal).modes_hz()
    b, t = BaseParams(**nominal["base"]), TMDParams(**nominal["tmd"])
    inert = t.inertance if t.inerter != InerterModel.NONE else 0.0
    mass = np.array([[b.mass + inert, -inert], [-inert, t.mass + inert]])
    stiff = np.array([[b.stiffness + t.stiffness, -t.stiffness], [-t.stiffness, t.stiffness]])
    if t.mass + inert <= 0.0:  # no TMD node: the base alone
        return [math.sqrt(b.stiffness / b.mass) / (2 * math.pi)]
    w2 = np.linalg.eigvals(np.linalg.solve(mass, stiff)).real
    return sorted(math.sqrt(max(float(v), 0.0)) / (2 * math.pi) for v in w2)


def check_frame_records(records: list, nominal: dict, yml: Path) -> None:
    """A frame's records are transient records with storey channels ``x<i>``, ``x<i>dd`` (i = 1..n), the
    TMD's ``y``, ``ydd`` and the force; the pair's ``x``, ``xdd`` have no place there, nor storey
    channels beside a base + TMD nominal (DataError naming the record and the column)."""
    frame = "frame" in nominal
    n = int(nominal["frame"]["storeys"]) if frame else 0
    for r in records:
        file = yml.parent / r.name
        cols = storey_columns(r.columns)
        if not frame:
            if cols:
                raise data_error(
                    file,
                    f"storey channel {cols[0]!r} in a dataset whose nominal is the base + TMD pair (a frame's "
                    "records need a nominal with a 'frame:' block)",
                    column=cols[0],
                )
            continue
        if r.kind != "transient":
            raise data_error(
                file,
                f"a frame is diagnosed from transient records (kind: transient, columns t, force, x<i>dd, ...); "
                f"this record is of kind {r.kind!r}",
            )
        for c in ("x", "xdd"):
            if c in r.columns:
                raise data_error(
                    file,
                    f"column {c!r} is the pair's base channel: a frame's storey channels are x<i> / x<i>dd (storey i, "
                    "1 = lowest)",
                    column=c,
                )
        for c in cols:
            i = int(c[1:].removesuffix("dd"))
            if i > n:
                raise data_error(file, f"storey {i} does not exist: the nominal frame has {n} storeys", column=c)
        if not cols and not any(c in r.columns for c in ("y", "ydd")):
            raise data_error(file, "no response channel (x<i>, x<i>dd, y, ydd) to diagnose the frame from", column="t")


def check_time_base(records: list, nominal: dict, yml: Path) -> None:
    """Refuse a time record whose sampling rate puts a mode of the nominal model at or above the
    Nyquist frequency: the record cannot show that mode, and the usual cause is a time column in
    milliseconds (1000 times too slow a rate), which would otherwise run for many minutes and end in a
    meaningless verdict. Named with the numbers: the rate, the mode, what the rate would be in ms."""
    modes = nominal_modes_hz(nominal)
    top = modes[-1] if modes else 0.0
    if not top > 0.0:
        return
    for r in records:
        if r.kind not in ("time", "transient") or "t" not in r.columns or len(r.columns["t"]) < 2:
            continue
        t = r.columns["t"]
        span = float(t[-1] - t[0])
        if not span > 0.0:
            continue
        block = int((r.meta.get("reduced") or {}).get("block", 1))
        fs = (len(t) - 1) / span * block  # the rate the rig sampled at (before any averaging on reading)
        if top < 0.5 * fs:
            continue
        hint = (
            f"; if the time column is in milliseconds, the rate is {1000 * fs:.4g} Hz: give t in seconds"
            if top < 500.0 * fs
            else ""
        )
        raise data_error(
            yml.parent / r.name,
            f"the time column samples at {fs:.4g} Hz (a step of {1 / fs:.4g} s over {span:.4g} s): the nominal "
            f"model's mode at {top:.4g} Hz (modes {', '.join(f'{m:.4g}' for m in modes)} Hz) lies above the "
            f"Nyquist frequency fs/2 = {0.5 * fs:.4g} Hz{hint}",
            column="t",
        )
