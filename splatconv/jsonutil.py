"""Strict JSON decoding with errors that say where, bounded for hostile input.

Every JSON a user hands splatconv (a ``.splatv`` header, the cameras comment of a
PLY, ``--cameras``, ``--view``) goes through :func:`decode`: nesting deeper than
:data:`MAX_DEPTH` and numbers a double cannot hold are refused before they can
reach code that would recurse or overflow on them.
"""

from __future__ import annotations

import json
import math
import re
import sys

import numpy as np

from .errors import FormatError

#: Deepest nesting of arrays and objects accepted. A ``.splatv`` header needs 4
#: (chunks, chunk, cameras, rotation rows); Python's decoder recurses once a level
#: and fails near 1,000.
MAX_DEPTH = 64

#: A JSON string, escapes included (unrolled so that it runs in linear time).
_STRING = re.compile(rb'"[^"\\]*(?:\\.[^"\\]*)*"', re.DOTALL)
#: Every byte but the four brackets, for ``bytes.translate``'s delete argument.
_NOT_BRACKETS = bytes(b for b in range(256) if b not in b"[]{}")
_OPENERS = np.frombuffer(b"[{", np.uint8)


class JSONLimitError(ValueError):
    """JSON that is well formed but past a bound (depth, number size)."""


class JSONSyntaxError(ValueError):
    """Text that is not JSON; ``msg`` is the reason without the position."""

    def __init__(self, msg: str, lineno: int, colno: int):
        super().__init__(f"{msg} (line {lineno}, column {colno})")
        self.msg = msg


def nesting_depth(raw: bytes) -> int:
    """Deepest nesting of ``[`` / ``{`` in ``raw``, outside strings.

    Exact for valid JSON, and never below the depth Python's decoder reaches
    before it finds a syntax error, so checking it first bounds the decoder.
    """
    if raw.count(b"[") + raw.count(b"{") <= MAX_DEPTH:
        return 0  # cannot be deeper; skips the scan for ordinary headers
    brackets = _STRING.sub(b"", raw).translate(None, _NOT_BRACKETS)
    if not brackets:
        return 0
    codes = np.frombuffer(brackets, np.uint8)
    steps = np.where(np.isin(codes, _OPENERS), np.int32(1), np.int32(-1))
    return int(np.cumsum(steps, dtype=np.int64).max())


def _reject_constant(name: str):
    raise JSONLimitError(f"{name} is not allowed in strict JSON")


def _parse_float(text: str) -> float:
    value = float(text)
    if math.isinf(value):
        raise JSONLimitError(f"number {_short(text)} is past the largest double")
    return value


def _parse_int(text: str) -> int:
    # Past 309 digits no double holds it (and Python's own limit is 4,300 digits);
    # a JavaScript viewer would read it as Infinity.
    if len(text.lstrip("-")) > 309 or abs(int(text)) > sys.float_info.max:
        raise JSONLimitError(f"number {_short(text)} is past the largest double")
    return int(text)


def _short(text: str) -> str:
    return text if len(text) <= 24 else f"{text[:12]}...({len(text)} digits)"


def decode(raw):
    """Decode strict, bounded JSON.

    Parameters
    ----------
    raw : bytes or str
        UTF-8 when bytes.

    Returns
    -------
    object
        The decoded value; every number is finite as a double.

    Raises
    ------
    ValueError
        With a message that says what is wrong (and where, for syntax errors);
        ``UnicodeDecodeError`` for bytes that are not UTF-8.
    """
    if isinstance(raw, str):
        encoded = raw.encode("utf-8", "surrogatepass")
    else:
        encoded = bytes(raw)
        raw = encoded.decode("utf-8")
    depth = nesting_depth(encoded)
    if depth > MAX_DEPTH:
        raise JSONLimitError(f"nested {depth} levels deep, more than the {MAX_DEPTH} allowed")
    try:
        return json.loads(raw, parse_constant=_reject_constant, parse_float=_parse_float, parse_int=_parse_int)
    except json.JSONDecodeError as e:
        raise JSONSyntaxError(e.msg, e.lineno, e.colno) from None
    except RecursionError:  # pragma: no cover - the depth check comes first
        raise JSONLimitError("nested too deeply") from None


def loads_strict(raw, path, label: str, where=()):
    """Decode UTF-8 JSON, rejecting ``NaN``, ``Infinity``, deep nesting and huge numbers.

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
    try:
        return decode(raw)
    except UnicodeDecodeError as e:
        raise FormatError(f"{label}: not UTF-8 (byte {e.start})", path, where) from None
    except ValueError as e:
        raise FormatError(f"{label}: {e}", path, where) from None


def is_finite_number(value) -> bool:
    """True for an int or float (not a bool) that is finite as a double."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return False
    if isinstance(value, int):
        return abs(value) <= sys.float_info.max
    return math.isfinite(value)
