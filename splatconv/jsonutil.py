"""Strict JSON decoding with errors that say where."""

from __future__ import annotations

import json

from .errors import FormatError


def _reject_constant(name: str):
    raise ValueError(f"{name} is not allowed in strict JSON")


def loads_strict(raw, path, label: str, where=()):
    """Decode UTF-8 JSON, rejecting ``NaN`` and ``Infinity``.

    Parameters
    ----------
    raw : bytes or str
    path : str
        The file, for the error message.
    label : str
        What the JSON is (``"header JSON"``, ``"invalid JSON"``), the message prefix.

    Raises
    ------
    FormatError
    """
    if isinstance(raw, (bytes, bytearray)):
        try:
            raw = raw.decode("utf-8")
        except UnicodeDecodeError as e:
            raise FormatError(f"{label}: not UTF-8 (byte {e.start})", path, where) from None
    try:
        return json.loads(raw, parse_constant=_reject_constant)
    except json.JSONDecodeError as e:
        raise FormatError(f"{label}: {e.msg} (line {e.lineno}, column {e.colno})", path, where) from None
    except ValueError as e:
        raise FormatError(f"{label}: {e}", path, where) from None
