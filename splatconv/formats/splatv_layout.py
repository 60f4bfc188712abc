"""The ``.splatv`` record and texture layout, as data (see ``specs/splatv.md``).

One place for the facts both the reader/writer (:mod:`splatconv.formats.splatv`)
and the packing engine (:mod:`splatconv.formats.splatv_engine`) use, so the two
import it and never each other.
"""

from __future__ import annotations

import json
import struct

MAGIC = 0x674B
PREAMBLE = struct.Struct("<II")
TEXWIDTH = 4096
WORDS_PER_SPLAT = 16
SPLATS_PER_ROW = TEXWIDTH * 4 // WORDS_PER_SPLAT  # 1024: the shader's index & 0x3ff
RECORD_BYTES = WORDS_PER_SPLAT * 4
#: Largest JSON header read (a header is cameras and a few numbers).
MAX_JSON_BYTES = 64 << 20
#: Largest texture height accepted: past any GPU's MAX_TEXTURE_SIZE (4 GiB of data).
MAX_TEXHEIGHT = 65536

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

#: Bytes of one RGBA32UI texel.
TEXEL_BYTES = 16


def texture_height(count: int) -> int:
    """Rows of the texture for ``count`` splats: ceil(count / 1024)."""
    return -(-count // SPLATS_PER_ROW)


def texture_bytes(texheight: int) -> int:
    """Bytes of a texture of ``texheight`` rows."""
    return TEXWIDTH * texheight * TEXEL_BYTES


def header_bytes(count: int, cameras: list) -> bytes:
    """The preamble and JSON header for a file of ``count`` splats."""
    texheight = texture_height(count)
    chunk = {
        "type": "splat",
        "size": texture_bytes(texheight),
        "texwidth": TEXWIDTH,
        "texheight": texheight,
        "cameras": cameras,
    }
    text = json.dumps([chunk], separators=(",", ":"), ensure_ascii=False, allow_nan=False).encode("utf-8")
    return PREAMBLE.pack(MAGIC, len(text)) + text
