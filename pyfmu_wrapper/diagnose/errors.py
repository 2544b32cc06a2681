"""The error of bad measured data, shared by the data reader and the acquisition corrections."""

from __future__ import annotations

from ..errors import InputError


class DataError(InputError):
    """Bad measured data; the message names the file, row and column."""
