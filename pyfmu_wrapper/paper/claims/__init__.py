"""The claims of Brzeski & Perlikowski (2017), each judged by a computed comparison.

A claim is a row: what the paper says, the number the project computes (:mod:`..claim_data`), the
reference value, the threshold beside it, and the verdict *from* the comparison (:class:`Check`):
'agrees' when every check passes, 'disagrees' when none does, 'partly' otherwise. A claim whose
scenario was not run is a flagged row ('not computed'); one whose computation fails is a flagged
row ('error') carrying the exception, and the report command exits non-zero. No verdict is written
by hand. The table :data:`CLAIMS` (:mod:`.table`) lists the claims in report order with the scenarios they need.
"""

from . import sect2_4, sect5, sect6_7  # noqa: F401 - the sections fill CLAIMS, in report order
from .table import CLAIMS, Check, Claim, Context, Entry, claim, evaluate, fmt

__all__ = ["CLAIMS", "Check", "Claim", "Context", "Entry", "claim", "evaluate", "fmt"]
