"""The ``.splatv`` record and texture layout, as data (see ``specs/splatv.md``).

One place for the facts both the reader/writer (:mod:`splatconv.formats.splatv`)
and the packing engine (:mod:`splatconv.formats.splatv_engine`) use, so the two
import it and never each other.
"""

from __future__ import annotations

import json
import struct

import numpy as np

from .. import packing, viewer
# The texture's geometry is the viewer's; the record layout on top of it is this format's.
from ..viewer import SPLATS_PER_ROW, TEXEL_BYTES, TEXWIDTH, WORDS_PER_SPLAT, texture_bytes, texture_height  # noqa: F401

MAGIC = 0x674B
PREAMBLE = struct.Struct("<II")
RECORD_BYTES = WORDS_PER_SPLAT * 4
#: Largest JSON header read (a header is cameras and a few numbers).
MAX_JSON_BYTES = 64 << 20
#: Largest texture height accepted: past any GPU's MAX_TEXTURE_SIZE (4 GiB of data).
MAX_TEXHEIGHT = 65536
#: Key of the splat chunk holding the number of splats (splatconv's; the viewer
#: ignores it). Without it a splat whose record is all zero cannot be told from padding.
COUNT_KEY = "count"

#: Record words 0-2: position as float32 bits.
POSITION_WORDS = {0: "x", 1: "y", 2: "z"}
#: Record words holding two halves (low 16 bits first); None is an unused zero half.
HALF_WORDS = {
    3: ("rot_0", "rot_1"),
    4: ("rot_2", "rot_3"),
    5: ("scale_0", "scale_1"),
    6: ("scale_2", None),
    8: ("motion_0", "motion_1"),
    9: ("motion_2", "motion_3"),
    10: ("motion_4", "motion_5"),
    11: ("motion_6", "motion_7"),
    12: ("motion_8", None),
    13: ("omega_0", "omega_1"),
    14: ("omega_2", "omega_3"),
    15: ("trbf_center", "trbf_scale"),
}
#: Record word 7: RGBA8, R in the low byte.
COLOR_WORD = 7
#: Attributes the texture stores as exp(value) (the model keeps logarithms).
EXP_ATTRIBUTES = frozenset({"scale_0", "scale_1", "scale_2", "trbf_scale"})



def header_bytes(count: int, cameras: list) -> bytes:
    """The preamble and JSON header for a file of ``count`` splats."""
    texheight = texture_height(count)
    chunk = {
        "type": "splat",
        "size": texture_bytes(texheight),
        "texwidth": TEXWIDTH,
        "texheight": texheight,
        COUNT_KEY: count,
        "cameras": cameras,
    }
    text = json.dumps([chunk], separators=(",", ":"), ensure_ascii=False, allow_nan=False).encode("utf-8")
    return PREAMBLE.pack(MAGIC, len(text)) + text


# --------------------------------------------------------------------------
# Inverse tables: texture value -> model value, chosen so that both writers
# give the same texture value back.

#: Logit written for alpha bytes 0 and 255 (kept finite): sigmoid(-40)*255 is
#: below 1e-15 and sigmoid(40)*255 is exactly 255.0 in double precision, so both
#: writers (rounding and truncating) give the byte back.
ALPHA_LOGIT_LIMIT = np.float32(40.0)

# --------------------------------------------------------------------------
# Inverse tables: texture value -> model value, chosen so that both writers
# give the same texture value back.


def _nudge_up(start: np.ndarray, ok) -> np.ndarray:
    """Smallest float32 at or above ``start`` (element-wise) where ``ok`` holds.

    A handful of ulp steps always suffices for the tables below; the loop runs
    over steps, not values.
    """
    value = start.astype(np.float32)
    for _ in range(64):
        bad = ~ok(value)
        if not bad.any():
            return value
        value[bad] = np.nextafter(value[bad], np.float32(np.inf))
    raise AssertionError("inverse table did not converge")  # pragma: no cover


def _log_table() -> np.ndarray:
    """Model value (a logarithm) for each half stored in an exp() slot."""
    v = packing.HALF_TO_FLOAT
    bits = np.arange(1 << 16, dtype=np.uint32)
    table = np.full(1 << 16, np.nan, dtype=np.float32)
    pos = (bits & packing.HALF_SIGN_BIT == 0) & np.isfinite(v) & (v > 0)
    target = v[pos].astype(np.float64)
    with np.errstate(divide="ignore"):
        start = np.log(target)
    # float32(exp(L)) >= v makes truncation give v back; rounding does too since
    # each step moves exp(L) by far less than half a half-ulp.
    table[pos] = _nudge_up(start, lambda L: np.exp(L.astype(np.float64)).astype(np.float32) >= target)
    table[bits == 0] = -np.inf
    table[bits == packing.HALF_SIGN_BIT] = -np.inf  # -0 has no logarithm; exp(-inf) gives +0 (reported)
    table[bits == packing.HALF_INF_BITS] = np.inf
    nan = np.isnan(v)
    table[nan] = v[nan]  # NaN passes through both ways with its payload
    table.flags.writeable = False
    return table


def _color_table() -> np.ndarray:
    """Model colour for each byte: smallest float32 f >= c/255 with f*255 >= c."""
    c = np.arange(256, dtype=np.float64)
    table = _nudge_up(c / 255.0, lambda f: f.astype(np.float64) * 255.0 >= c)
    table.flags.writeable = False
    return table


def _sigmoid255(logit: np.ndarray) -> np.ndarray:
    """Alpha byte value before rounding, computed the way splaTV's JS does (double): sigmoid, then x255."""
    return viewer.sigmoid(logit) * 255.0


def _alpha_table() -> np.ndarray:
    """Model opacity (a logit) for each alpha byte."""
    a = np.arange(1, 255, dtype=np.float64)
    p = a / 255.0
    # A margin of 1e-9 above the byte keeps truncation safe from a last-bit
    # difference between this libm's exp and a browser's.
    mid = _nudge_up(np.log(p / (1.0 - p)), lambda L: _sigmoid255(L) >= a + 1e-9)
    table = np.concatenate([[-ALPHA_LOGIT_LIMIT], mid, [ALPHA_LOGIT_LIMIT]]).astype(np.float32)
    table.flags.writeable = False
    return table


LOG_OF_HALF = _log_table()
COLOR_OF_BYTE = _color_table()
LOGIT_OF_BYTE = _alpha_table()
