"""The names the ``reproduce`` command offers, in a module that imports nothing heavy (its ``--help``
and its argument checks run before the engines are imported): the paper's cases and scenarios, and
the default engine. :mod:`.reproduce` runs them."""

from __future__ import annotations

CASES = (1, 2, 3)
#: the scenarios of scenarios/paper/, one per figure and case
NAMES = ["fig2_iratio"] + [f"fig{f}_case{c}" for f in (3, 4, 5, 6) for c in CASES]
DEFAULT_ENGINE = "monolithic"
