"""What a model unit tells the Modelica generator: the source of its Modelica subpackage (a ``.mo``
file in the unit's own folder), the class for a TMD configuration, the Modelica modifiers of a
structure, its cases and where each Modelica state variable sits in the unit's state (for the test
against the monolithic solver). :mod:`pyfmu_wrapper.generate.modelica` writes the subpackage into
the package ``modelica/TMDInerter`` and every unit's cases from here.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .params import TMDParams


@dataclass(frozen=True)
class ModelicaCase:
    """One case model (``TMDInerter.Cases.<name>``) and the Python parameters it stands for."""

    name: str  #: a Modelica class name
    description: str
    structure: Any  #: the unit's structure
    tmd: TMDParams


@dataclass(frozen=True)
class ModelicaSource:
    """A unit's part of the Modelica package."""

    #: the hand-written source of the unit's subpackage (``within TMDInerter; package <stem> ...``),
    #: in the unit's folder; the generator writes it into the package as ``<stem>.mo`` with its
    #: generated parameter blocks filled from the parameter registry (like Systems.mo's)
    source: Path
    #: system(tmd) -> the class a case of this TMD configuration extends (inside the package, e.g.
    #: ``Frames.FrameIdealInerter``)
    system: Callable[[TMDParams], str]
    #: modifiers(structure) -> Modelica parameter name -> its value as a Modelica literal (the
    #: structure's parameters; the generator adds the TMD's from the parameter registry)
    modifiers: Callable[[Any], dict[str, str]]
    #: cases() -> the unit's cases, written to Cases.mo
    cases: Callable[[], tuple[ModelicaCase, ...]]
    #: states(structure) -> Modelica variable name -> index in the unit's state
    states: Callable[[Any], dict[str, int]]

    @property
    def file(self) -> str:
        """The file name of the subpackage inside the package."""
        return self.source.name

    @property
    def package(self) -> str:
        """The subpackage's name (the source's stem)."""
        return self.source.stem
