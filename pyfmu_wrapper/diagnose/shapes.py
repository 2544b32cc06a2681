"""The shapes of the diagnoses that their split-off helpers read, as :class:`typing.Protocol` classes:
a helper (report, verdict, plots, outcome, screening) takes an object of this shape and imports nothing
of the facade that calls it, so there is no import circle, not even for annotations. Each member is
what some helper reads (read-only; typed ``Any``: the facade documents the values)."""

from __future__ import annotations

from typing import Any, Protocol


class SystemDiagnosisShape(Protocol):
    """A finished system diagnosis (:class:`~.system.diagnosis.SystemDiagnosis`), as its report helpers (:mod:`.system.outcome`, :mod:`.verdict`, :mod:`.plotting`) read it."""

    @property
    def _cand(self) -> Any: ...

    @property
    def _spike_sd(self) -> Any: ...

    @property
    def cands(self) -> Any: ...

    @property
    def chi0(self) -> Any: ...

    @property
    def chi0_f(self) -> Any: ...

    @property
    def chi0_t(self) -> Any: ...

    @property
    def chosen(self) -> Any: ...

    @property
    def cur(self) -> Any: ...

    @property
    def dof(self) -> Any: ...

    @property
    def dof_t(self) -> Any: ...

    @property
    def final(self) -> Any: ...

    @property
    def frc(self) -> Any: ...

    @property
    def frc_ev(self) -> Any: ...

    @property
    def held_out(self) -> Any: ...

    @property
    def hint(self) -> Any: ...

    @property
    def localisation(self) -> Any: ...

    @property
    def agreement(self) -> Any: ...

    @property
    def gap_left(self) -> Any: ...

    @property
    def model(self) -> Any: ...

    @property
    def motion(self) -> Any: ...

    @property
    def n(self) -> Any: ...

    @property
    def nf(self) -> Any: ...

    @property
    def noise_ok(self) -> Any: ...

    @property
    def params(self) -> Any: ...

    @property
    def play(self) -> Any: ...

    @property
    def play_ok(self) -> Any: ...

    @property
    def singles(self) -> Any: ...

    @property
    def test_ids(self) -> Any: ...

    @property
    def unexplained(self) -> Any: ...

    @property
    def unexplained_share(self) -> Any: ...

    @property
    def views(self) -> Any: ...


class FRCDiagnosisShape(Protocol):
    """A finished FRC diagnosis (:class:`~.system.frc.FRCDiagnosis`), as its report (:mod:`.system.frc_report`) and :func:`.plotting.plot_frc` read it."""

    @property
    def chosen(self) -> Any: ...

    @property
    def fits(self) -> Any: ...

    @property
    def hint(self) -> Any: ...

    @property
    def names(self) -> Any: ...

    @property
    def noise(self) -> Any: ...

    @property
    def noise_rel(self) -> Any: ...

    @property
    def pred0(self) -> Any: ...

    @property
    def rss0(self) -> Any: ...

    @property
    def structural(self) -> Any: ...

    @property
    def test(self) -> Any: ...

    @property
    def train(self) -> Any: ...

    @property
    def w(self) -> Any: ...

    @property
    def x(self) -> Any: ...


class TransientDiagnosisShape(Protocol):
    """A transient diagnosis (:class:`~.system.transient.TransientDiagnosis`), as its screening (:mod:`.system.transient_screen`) and :func:`.plotting.plot_transient` read it."""

    @property
    def log(self) -> Any: ...

    @property
    def nominal_resid(self) -> Any: ...

    @property
    def p_nom(self) -> Any: ...

    @property
    def sc(self) -> Any: ...

    @property
    def views(self) -> Any: ...
