"""Damaged ``.splatvq`` files for the tests: the block table read back, entries, payloads and codes changed.

Test-only code, shared by ``tests/test_splatvq.py`` (what splatconv's reader
refuses) and ``tests/test_web_splatvq.py`` (what the page refuses). Every change
is to the first block unless said otherwise.
"""

from __future__ import annotations

import json
import zlib

import numpy as np

from splatconv.formats import splatvq
from splatconv.formats import splatvq_codec as codec


def setting(data: bytes) -> codec.Setting:
    """The setting a file's preamble holds."""
    values = splatvq.PREAMBLE.unpack_from(data)[3:3 + len(splatvq.SETTING_ORDER)]
    return codec.Setting(**dict(zip(splatvq.SETTING_ORDER, values)))


def layout(data: bytes):
    """Where the block table starts, its entries (coded, raw, payload, stored) and where the blocks start."""
    json_length, _json_size, blocks = splatvq.PREAMBLE.unpack_from(data)[-3:]
    table_at = splatvq.PREAMBLE.size + json_length
    entries = list(splatvq.BLOCK_ENTRY.iter_unpack(data[table_at:table_at + blocks * splatvq.BLOCK_ENTRY.size]))
    return table_at, entries, table_at + blocks * splatvq.BLOCK_ENTRY.size


def with_entry(data: bytes, i: int = 0, *, coded=None, raw=None, payload=None, stored=None, body=None) -> bytes:
    """Block ``i``'s table entry with the values given changed; ``body`` replaces every block's bytes."""
    table_at, entries, body_at = layout(data)
    at = table_at + i * splatvq.BLOCK_ENTRY.size
    entry = splatvq.BLOCK_ENTRY.pack(*(old if new is None else new
                                       for old, new in zip(entries[i], (coded, raw, payload, stored))))
    rest = data[at + splatvq.BLOCK_ENTRY.size:] if body is None else data[at + splatvq.BLOCK_ENTRY.size:body_at] + body
    return data[:at] + entry + rest


def header_json(data: bytes) -> dict:
    """The header JSON of a file (inflated and parsed)."""
    table_at, _, _ = layout(data)
    return json.loads(zlib.decompress(data[splatvq.PREAMBLE.size:table_at], -15))


def with_header(data: bytes, stored: bytes, size: int) -> bytes:
    """The header's stored bytes replaced by ``stored``, the preamble declaring them and ``size`` inflated."""
    head = splatvq.PREAMBLE.unpack_from(data)
    table_at, _, _ = layout(data)
    return splatvq.PREAMBLE.pack(*head[:-3], len(stored), size, head[-1]) + stored + data[table_at:]


def with_meta(data: bytes, meta: dict) -> bytes:
    """The header JSON replaced by ``meta``, deflated as the writer deflates it."""
    text = json.dumps(meta).encode()
    return with_header(data, splatvq.header_deflated(text), len(text))


def with_count(data: bytes, count) -> bytes:
    """The header JSON's count changed (the block table left as it is)."""
    meta = header_json(data)
    meta["count"] = count
    return with_meta(data, meta)


def deflate(payload: bytes) -> bytes:
    """Raw deflate, as any encoder might write it."""
    comp = zlib.compressobj(9, zlib.DEFLATED, -15)
    return comp.compress(payload) + comp.flush()


def payload(data: bytes) -> bytes:
    """The first block's payload (inflated)."""
    _, entries, start = layout(data)
    return zlib.decompress(data[start:start + entries[0][3]], -15)


def with_payload(data: bytes, new: bytes, declared: int | None = None) -> bytes:
    """The first block's payload replaced, deflated again; the table declares its size (or ``declared``)."""
    _, entries, start = layout(data)
    again = deflate(new)
    changed = with_entry(data, 0, payload=len(new) if declared is None else declared, stored=len(again))
    return changed[:start] + again + changed[start + entries[0][3]:]


def with_codes(data: bytes, change) -> bytes:
    """The first block's codes changed by ``change(tables, fields)`` and packed again (a damaged encoder)."""
    coded, raw = layout(data)[1][0][:2]
    tables, fields, raw_words = codec.unpack_payload(payload(data), coded, raw, "x", ())
    tables = {name: v.copy() for name, v in tables.items()}
    fields = {name: v.copy() for name, v in fields.items()}
    change(tables, fields)
    return with_payload(data, b"".join(codec.payload_parts(tables, fields, raw_words)))


def with_width(data: bytes, column: str, width: int) -> bytes:
    """The first block's width table saying ``width`` bytes for ``column`` (a name of ``WIDTH_COLUMNS``),
    its planes as they are."""
    changed = bytearray(payload(data))
    coded = layout(data)[1][0][0]
    at = -(-coded // codec.CHUNK) * codec.CHUNK_BYTES + codec.WIDTH_COLUMNS.index(column)
    assert changed[at] < width
    changed[at] = width
    return with_payload(data, bytes(changed))


def bad_rotation(tables, fields):
    """Splat 3's boost level 0 (``rotation_bits`` a component) and a rotation code of 4096, past them."""
    fields["window_index"][3] &= 0x3F
    fields["rotation"][3, 1] = 1 << 12


def bad_position_step(tables, fields):
    """The first two splats' x steps at their largest: the second's code passes 2**32 - 1."""
    fields["x_step"][:2] = 2 ** 32 - 1


def declaring(blocks: int, last: int = codec.BLOCK) -> bytes:
    """A ``.splatvq`` file of ``blocks`` blocks of zero codes (the last of ``last`` splats): valid, a few
    kilobytes a block (deflate gives some thousand to one), declaring ``blocks`` times 65,536 splats.

    What a hostile file looks like: tiny on disk, millions of splats once read. Made by the codec's own
    pieces: the setting of the default quality, the payload sizes :func:`codec.payload_bounds` gives.
    """
    sizes = [codec.BLOCK] * (blocks - 1) + [last]
    stored = {n: deflate(bytes(codec.payload_bounds(n, 0)[0])) for n in set(sizes)}
    meta = json.dumps({"count": sum(sizes), "setting": "default",
                       "cameras": [{"id": 0, "img_name": "c", "width": 64, "height": 64,
                                    "position": [0, 0, -5], "rotation": [[1, 0, 0], [0, 1, 0], [0, 0, 1]],
                                    "fx": 64, "fy": 64}]}).encode()
    values = [getattr(codec.SETTINGS["default"], f) for f in splatvq.SETTING_ORDER]
    packed = splatvq.header_deflated(meta)
    head = splatvq.PREAMBLE.pack(splatvq.MAGIC, splatvq.VERSION, codec.CODER_DEFLATE_RAW, *values,
                                 codec.CHUNK_LOG2, len(packed), len(meta), blocks)
    table = b"".join(splatvq.BLOCK_ENTRY.pack(n, 0, codec.payload_bounds(n, 0)[0], len(stored[n])) for n in sizes)
    return head + packed + table + b"".join(stored[n] for n in sizes)


def rearranged(data: bytes, picks, corrupt: int | None = None) -> bytes:
    """A valid file of ``data``'s blocks in the order of ``picks`` (indices of its blocks, each as
    often as named), its count their splats. With ``corrupt``, the first byte of the block at that
    place in ``picks`` makes it a stored deflate block of the reserved type, which no inflater accepts."""
    table_at, entries, start = layout(data)
    head = splatvq.PREAMBLE.unpack_from(data)
    ends = np.cumsum([0] + [entry[3] for entry in entries]) + start
    body = [data[ends[i]:ends[i + 1]] for i in picks]
    if corrupt is not None:
        body[corrupt] = bytes([0x07]) + body[corrupt][1:]
    whole = (splatvq.PREAMBLE.pack(*head[:-1], len(picks)) + data[splatvq.PREAMBLE.size:table_at]
             + b"".join(splatvq.BLOCK_ENTRY.pack(*entries[i]) for i in picks) + b"".join(body))
    return with_count(whole, sum(entries[i][0] + entries[i][1] for i in picks))


#: Raw records whose importance keys take every path of a decoder's order: (scale halves, alpha byte) each,
#: and the order they decode in (ties, -0, negative and NaN keys, the largest key there is).
ODD_KEYS = ((0x3C00, 0x3C00, 0x3C00, 10), (0x8000, 0x3C00, 0x3C00, 200), (0x7E00, 0x3C00, 0x3C00, 255),
            (0xBC00, 0x4000, 0x3C00, 1), (0x4000, 0x3C00, 0x4100, 2), (0x0000, 0x3C00, 0x3C00, 9),
            (0xBC00, 0x3C00, 0x3C00, 1), (0x7C00, 0x0000, 0x3C00, 3), (0x7BFF, 0x7BFF, 0x7BFF, 255))
ODD_KEYS_ORDER = (8, 0, 4, 1, 5, 6, 3, 2, 7)


def odd_key_records() -> np.ndarray:
    """:data:`ODD_KEYS` as records, ``(9, 16) uint32`` (a unit rotation; nothing else set)."""
    raw = np.zeros((len(ODD_KEYS), 16), "<u4")
    for i, (h0, h1, h2, alpha) in enumerate(ODD_KEYS):
        raw[i, 3], raw[i, 5], raw[i, 6], raw[i, 7] = 0x3C00, h0 | h1 << 16, h2, alpha << 24
    return raw


def with_raw_only(data: bytes, raw: np.ndarray) -> bytes:
    """A one-block file whose block holds ``raw`` records only."""
    changed = with_entry(data, 0, coded=0, raw=len(raw))
    return with_count(with_payload(changed, bytes(len(codec.WIDTH_COLUMNS)) + raw.tobytes()), len(raw))
