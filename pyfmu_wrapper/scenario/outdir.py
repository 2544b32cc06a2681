"""The results folder of run-scenario: where it goes, and its checkpoints.

The rules that keep the tool from losing anything it did not write are shared by every writer:
:mod:`pyfmu_wrapper.safeio` (checked before computing and again at the swap; file hashes in the
marker). Here: run-scenario's marker, its protected folders (besides the current and home folders,
the folder of the scenario file), the rule that a result of another scenario file is never replaced,
and the checkpoint folder ``<out>.checkpoints/`` beside the output folder
(:func:`default_checkpoint_dir`), one per output folder, with its own marker: a folder of that name
that is not ours, or a ``--cache`` that is a file or unwritable, is refused before computing.
"""

from __future__ import annotations

import os
from importlib import metadata
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..safeio import OutputError, ResultFolder, abs_path
from ..safeio.tree import read_marker

if TYPE_CHECKING:
    from .schema import Scenario

#: the marker file of every folder run-scenario writes (results, partial folders, checkpoints)
MARKER = ".run-scenario.json"
TOOL = "run-scenario"

__all__ = ["MARKER", "TOOL", "OutputError", "abs_path", "check_output_dir", "default_checkpoint_dir"]


def tool_version() -> str | None:
    """The installed version of this package (None when it runs from a source tree not installed)."""
    try:
        return metadata.version("pyfmu-wrapper")
    except metadata.PackageNotFoundError:  # pragma: no cover
        return None


def default_output_dir(scn: Scenario) -> Path:
    """Where a scenario's results go when no ``--out`` is given: ``results/<scenario name>``."""
    return Path("results") / scn.name


def default_checkpoint_dir(out_dir: str | os.PathLike[str]) -> Path:
    """Where the resumable checkpoints of a results folder live: ``<out>.checkpoints/`` beside it
    (one folder per output folder: ``--out /tmp/foo`` -> ``/tmp/foo.checkpoints/``)."""
    out = abs_path(out_dir)
    if out.parent == out or not out.name:
        raise OutputError(f"--out {os.fspath(out_dir)}: refusing to write results to the root folder")
    return out.with_name(out.name + ".checkpoints")


def result_folder(out: str | os.PathLike[str], scenario_path: str | None) -> ResultFolder:
    """The results folder of a run of the scenario file ``scenario_path``."""
    protect = [] if scenario_path is None else [("the scenario file", abs_path(scenario_path))]
    same = {} if scenario_path is None else {"scenario_file": str(abs_path(scenario_path))}
    return ResultFolder(out, TOOL, MARKER, protect=protect, same=same)


def check_checkpoint_dir(out: Path, checkpoint_dir: Path | None) -> None:
    """A ``--cache`` that is a file, a symbolic link or unwritable, or a ``<out>.checkpoints`` that is
    not ours: refused (OutputError) before computing."""
    if checkpoint_dir is None:
        return
    ck = abs_path(checkpoint_dir)
    opt = "--out" if ck == default_checkpoint_dir(out) else "--cache"
    if ck.is_symlink() or (ck.exists() and not ck.is_dir()):
        raise OutputError(
            f"{opt} {out if opt == '--out' else checkpoint_dir}: the checkpoint folder {ck} is a file or a link, not a folder"
        )
    if opt == "--out" and ck.exists():
        m = read_marker(ck, MARKER, TOOL)
        if (m is None or m.get("kind") != "checkpoints") and os.listdir(ck):
            raise OutputError(
                f"--out {out}: the checkpoint folder {ck} exists but was not written by run-scenario; refusing to "
                "write into it (move it, or choose another --out)"
            )
    probe = ck if ck.exists() else next((p for p in ck.parents if p.exists()), None)
    if probe is not None and (not probe.is_dir() or not os.access(probe, os.W_OK | os.X_OK)):
        raise OutputError(f"{opt}: cannot write checkpoints into {ck} ({probe} is not a writable folder)")


def check_output_dir(
    out: str | os.PathLike[str], scenario_path: str | None = None, checkpoint_dir: Path | None = None
) -> list[str]:
    """Refuse an output folder whose replacement could lose anything run-scenario did not write
    (:class:`OutputError`, before any computing), clean the stale partial folders of killed runs.
    Returns the notes to show."""
    notes = result_folder(out, scenario_path).check()
    check_checkpoint_dir(abs_path(out), checkpoint_dir)
    return notes


def checkpoint_marker(out: Path) -> dict[str, Any]:
    return dict(
        tool=TOOL,
        version=tool_version(),
        kind="checkpoints",
        out=str(out),
        note="finished sweeps of run-scenario, for resuming a killed run; safe to delete",
    )
