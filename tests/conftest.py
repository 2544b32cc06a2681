"""Fixtures shared by the test modules."""

from __future__ import annotations

import pytest

from pyfmu_wrapper.scenario import output


@pytest.fixture
def no_computing(monkeypatch):
    """Fail if anything is computed: the refusals must come first."""

    def fail(*a, **k):
        raise AssertionError("run_studies was called: the output folder was not checked before computing")

    monkeypatch.setattr(output, "run_studies", fail)
