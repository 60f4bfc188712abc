"""The fuzz campaign: valid seed files, mutators, and a runner that checks every outcome.

Test-only code, shared by ``tests/test_fuzz.py`` (a short campaign in CI) and
``bench/bench_fuzz.py`` (a long one that prints figures). A mutant passes when
every command run on it (:func:`_commands`: ``info``, ``stats``, ``convert`` to every
format, ``bake``, ``render`` and ``diff``) either succeeds or prints note lines and one ``Error: ...`` line with
exit status 1, with no traceback, no warning, no file left behind (output, part
file or decompressed temporary), the input unchanged, and time and traced
memory under bounds.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import hashlib
import json
import os
import random
import struct
import tempfile
import time
import tracemalloc
import warnings
import zlib

import numpy as np
import zstandard
from click.testing import CliRunner

from splatconv.cli import main
from splatconv.formats import ply, splatvq
from splatconv.formats import splatvq_codec as vq_codec

from .conftest import GS_PROPS, lite_columns_with_normals, random_columns, write_ply

#: Ceiling on decompressed bytes during a campaign (``SPLATCONV_MAX_DECOMPRESSED``),
#: so that a bomb costs a fraction of a second; the default ceiling is tested apart.
CAMPAIGN_MAX_DECOMPRESSED = "64M"
#: Bounds a mutant must stay under, all commands together. The time is a deadline that catches a
#: hang, not a speed test: generous, so that a loaded machine (a mutant takes a second or two idle)
#: never trips it.
MAX_SECONDS = 120.0
MAX_TRACED_BYTES = 512 << 20

INTERESTING_INTS = [0, 1, -1, 2, 255, 256, 1023, 1024, 1025, 4095, 4096, 4097, 65535, 65536, 65537, -3000,
                    2**31 - 1, 2**31, 2**32, 2**32 + 1, 2**53 + 1, 2**63, 2**64, 10**12, 10**30]
INTERESTING_JSON = INTERESTING_INTS + [10**400, -10**400, 1.5, -0.0, 1e308, 1e-320, "x", "", None, True, False,
                                       [], {}, [[[[]]]], "1024"]
PLY_TYPES = ["char", "uchar", "short", "ushort", "int", "uint", "float", "double", "int8", "uint16", "float64",
             "bogus"]


def _camera(i: int) -> dict:
    return {"id": i, "img_name": f"cam{i:02d}", "width": 64, "height": 36, "position": [0.1 * i, 0, -6],
            "rotation": [[1, 0, 0], [0, 1, 0], [0, 0, 1]], "fy": 60.0, "fx": 60.0}


#: The static formats shared with other tools, each a seed written from the 3DGS PLY seed.
STATIC_SEEDS = ("scene.spz", "scene.compressed.ply", "scene.sog", "scene.glb")


def make_seeds(folder) -> list:
    """Small valid files of every kind the readers take; returns their paths."""
    folder = os.fspath(folder)
    cols = random_columns(40, seed=11)
    cols["x"][3] = np.nan
    cols["trbf_scale"][5] = np.inf
    lite = lite_columns_with_normals(cols)
    paths = [
        write_ply(os.path.join(folder, "lite.ply"), lite),
        write_ply(os.path.join(folder, "ascii.ply"), lite, text=True),
        write_ply(os.path.join(folder, "big_endian.ply"), lite, byte_order=">", extra_props=("extra",)),
    ]
    rng = np.random.default_rng(12)
    gs = {name: rng.normal(0, 1, 30).astype(np.float32) for name in GS_PROPS}
    paths.append(write_ply(os.path.join(folder, "gs.ply"), gs, dtype="f8"))
    # A list property in the vertex rows and an element after them.
    header = ["ply", "format binary_little_endian 1.0", "comment splatconv-cameras " + json.dumps([_camera(0)]),
              "element vertex 20"]
    header += [f"property float {name}" for name in ply.LITE_LAYOUT]
    header += ["property list uchar int idx", "element face 2", "property list uchar int vertex_indices",
               "end_header"]
    rows = b"".join(np.array([tuple(lite[c][i] for c in ply.LITE_LAYOUT)], ply.LITE_DTYPE).tobytes()
                    + struct.pack("<B2i", 2, i, i + 1) for i in range(20))
    faces = struct.pack("<B3i", 3, 0, 1, 2) + struct.pack("<B3i", 3, 2, 3, 4)
    listed = os.path.join(folder, "lists.ply")
    with open(listed, "wb") as f:
        f.write(("\n".join(header) + "\n").encode() + rows + faces)
    paths.append(listed)
    sv = os.path.join(folder, "scene.splatv")
    vq = os.path.join(folder, "scene.splatvq")
    runner = CliRunner()
    cams = os.path.join(folder, "cameras.json")
    with open(cams, "w") as f:
        json.dump([_camera(0), _camera(1)], f)
    splat = os.path.join(folder, "scene.splat")
    for args in (["convert", paths[0], sv, "--cameras", cams], ["convert", paths[3], splat],
                 ["convert", paths[0], vq, "--cameras", cams], ["convert", paths[0], vq + ".zst", "--zstd-level", "3"],
                 ["convert", paths[0], sv + ".zst", "--zstd-level", "3"],
                 ["convert", paths[3], os.path.join(folder, "gs.ply.zst"), "--zstd-level", "3"],
                 *(["convert", paths[3], os.path.join(folder, static)] for static in STATIC_SEEDS)):
        result = runner.invoke(main, [str(a) for a in args])
        assert result.exit_code == 0, result.output
    os.unlink(cams)
    paths += [sv, sv + ".zst", os.path.join(folder, "gs.ply.zst"), splat, vq, vq + ".zst",
              *(os.path.join(folder, static) for static in STATIC_SEEDS)]
    return [os.fspath(p) for p in paths]


# --------------------------------------------------------------------------
# Mutators: each takes (rng, content bytes, file name) and returns new content.


def _is_splatvq(name: str) -> bool:
    return name.lower().replace(".zst", "").endswith(".splatvq")


def _splatvq_parts(data: bytes):
    """(JSON stored length, block count, where the block table starts) of a .splatvq, or None if too short."""
    if len(data) < splatvq.PREAMBLE.size:
        return None
    fields = splatvq.PREAMBLE.unpack_from(data)
    return fields[-3], fields[-1], splatvq.PREAMBLE.size + fields[-3]


def _header_len(data: bytes) -> int:
    end = data.find(b"end_header")
    if data.startswith(b"ply") and end >= 0:
        return end + len(b"end_header\n")
    if data.startswith(splatvq.MAGIC) and (parts := _splatvq_parts(data)):
        return min(len(data), parts[2] + parts[1] * splatvq.BLOCK_ENTRY.size)
    if len(data) >= 8:
        return min(len(data), 8 + struct.unpack_from("<I", data, 4)[0])
    return len(data)


def _position(rng: random.Random, data: bytes) -> int:
    """A byte position, in the header half of the time."""
    if not data:
        return 0
    if rng.random() < 0.5:
        return rng.randrange(max(1, min(len(data), _header_len(data))))
    return rng.randrange(len(data))


def bit_flips(rng, data, _name):
    out = bytearray(data)
    for _ in range(rng.randint(1, 8)):
        if out:
            out[_position(rng, out)] ^= 1 << rng.randrange(8)
    return bytes(out)


def byte_values(rng, data, _name):
    out = bytearray(data)
    for _ in range(rng.randint(1, 4)):
        if out:
            at = _position(rng, out)
            run = rng.choice([1, 2, 4, 8])
            value = rng.choice([0x00, 0xFF, 0x7F, 0x80, 0x20, 0x0A])
            out[at:at + run] = bytes([value]) * len(out[at:at + run])
    return bytes(out)


def truncate(rng, data, _name):
    return data[:_position(rng, data)] if data else data


def extend(rng, data, _name):
    tail = rng.choice([bytes(rng.randrange(1, 5000)), os.urandom(rng.randrange(1, 500)), data[-rng.randrange(1, 200):],
                       b"\n1 2 3\n" * rng.randrange(1, 50)])
    return data + tail


def _ply_header_edit(rng, data):
    end = _header_len(data)
    lines = data[:end].decode("ascii", "replace").split("\n")
    body = data[end:]
    i = rng.randrange(len(lines))
    choice = rng.randrange(9)
    words = lines[i].split()
    if choice == 0 and len(lines) > 2:
        del lines[i]
    elif choice == 1:
        lines.insert(i, lines[i])
    elif choice == 2:
        j = rng.randrange(len(lines))
        lines[i], lines[j] = lines[j], lines[i]
    elif choice == 3 and words[:1] == ["property"] and len(words) == 3:
        lines[i] = f"property {rng.choice(PLY_TYPES)} {words[2]}"
    elif choice == 4:
        elements = [k for k, line in enumerate(lines) if line.startswith("element ")]
        if elements:
            k = rng.choice(elements)
            name = lines[k].split()[1] if len(lines[k].split()) > 1 else "vertex"
            count = rng.choice(INTERESTING_INTS + ["abc", "1e3", "0x10", "", "3 4"])
            lines[k] = f"element {name} {count}"
    elif choice == 5:
        lines[1] = "format " + rng.choice(["ascii 1.0", "binary_little_endian 1.0", "binary_big_endian 1.0",
                                           "binary_middle_endian 1.0", "ascii 2.0"])
    elif choice == 6:
        lines.insert(max(1, i), "property list " + rng.choice(PLY_TYPES) + " " + rng.choice(PLY_TYPES) + " l")
    elif choice == 7:
        lines.insert(2, "comment splatconv-cameras " + _hostile_json(rng, [_camera(0)]))
    else:
        lines.insert(max(1, i), rng.choice(["comment", "obj_info x", "element", "property float", "end_header",
                                            "\r", "element vertex 1", "property float x"]))
    return "\n".join(lines).encode("ascii", "replace") + body


def _replace_somewhere(rng, value, new):
    """``value`` with one randomly chosen leaf or member replaced by ``new`` (or deleted when new is ...)."""
    if isinstance(value, dict) and value and rng.random() < 0.8:
        key = rng.choice(list(value))
        out = dict(value)
        if new is Ellipsis:
            del out[key]
        else:
            out[key] = _replace_somewhere(rng, value[key], new)
        return out
    if isinstance(value, list) and value and rng.random() < 0.8:
        k = rng.randrange(len(value))
        out = list(value)
        if new is Ellipsis:
            del out[k]
        else:
            out[k] = _replace_somewhere(rng, value[k], new)
        return out
    return None if new is Ellipsis else new


def _hostile_json(rng, value) -> str:
    kind = rng.randrange(4)
    if kind == 0:
        depth = rng.choice([60, 70, 500, 1000, 5000])
        return json.dumps(_replace_somewhere(rng, value, "NEST")).replace('"NEST"', "[" * depth + "]" * depth)
    if kind == 1:
        return json.dumps(_replace_somewhere(rng, value, "BIG")).replace('"BIG"', rng.choice(
            ["1" + "0" * 400, "-1" + "0" * 309, "1e400", "-1e999", "1" + "0" * 5000, "NaN", "Infinity"]))
    if kind == 2:
        return json.dumps(_replace_somewhere(rng, value, Ellipsis))
    return json.dumps(_replace_somewhere(rng, value, rng.choice(INTERESTING_JSON)))


def _splatv_header_edit(rng, data):
    if len(data) < 8:
        return data
    json_len = struct.unpack_from("<I", data, 4)[0]
    try:
        chunks = json.loads(data[8:8 + json_len])
    except (ValueError, RecursionError):  # an earlier mutation nested it deeply
        return bit_flips(rng, data, "")
    body = data[8 + json_len:]
    text = _hostile_json(rng, chunks).encode()
    if rng.random() < 0.2:
        chunks[0]["count"] = rng.choice(INTERESTING_JSON)
        text = json.dumps(chunks).encode()
    declared = len(text) if rng.random() < 0.85 else rng.choice(INTERESTING_INTS[:20])
    return struct.pack("<II", struct.unpack_from("<I", data)[0], declared & 0xFFFFFFFF) + text + body


def _splatvq_header_edit(rng, data):
    parts = _splatvq_parts(data)
    if parts is None:
        return data
    json_len, blocks, table_at = parts
    try:
        meta = json.loads(zlib.decompressobj(-15).decompress(data[splatvq.PREAMBLE.size:table_at], 1 << 20))
    except (ValueError, RecursionError, UnicodeDecodeError, zlib.error):
        return bit_flips(rng, data, "")
    text = _hostile_json(rng, meta).encode()
    stored = splatvq.header_deflated(text)
    # The stored and the inflated length, each as it is or a lie.
    declared = [len(stored) if rng.random() < 0.85 else rng.choice(INTERESTING_INTS[:20]),
                len(text) if rng.random() < 0.85 else rng.choice(INTERESTING_INTS[:20])]
    preamble = bytearray(data[:splatvq.PREAMBLE.size])
    struct.pack_into("<II", preamble, splatvq.PREAMBLE.size - 12, declared[0] & 0xFFFFFFFF, declared[1] & 0xFFFFFFFF)
    if rng.random() < 0.3:  # a setting byte at an edge of its range or past it
        preamble[rng.randrange(6, 6 + len(splatvq.SETTING_ORDER))] = rng.choice([0, 1, 2, 8, 16, 30, 31, 127, 128, 255])
    return bytes(preamble) + stored + data[table_at:]


def header_edit(rng, data, name):
    if name.lower().replace(".zst", "").endswith(".ply"):
        return _ply_header_edit(rng, data)
    if _is_splatvq(name):
        return _splatvq_header_edit(rng, data)
    return _splatv_header_edit(rng, data)


def _splatvq_huge_count(rng, data):
    """A block table entry (coded, raw, payload or stored) or the header count that lies."""
    parts = _splatvq_parts(data)
    if parts is None or not parts[1]:
        return data
    json_len, blocks, table_at = parts
    out = bytearray(data)
    at = table_at + rng.randrange(blocks) * splatvq.BLOCK_ENTRY.size + 4 * rng.randrange(4)
    if at + 4 > len(out):
        return data
    old = struct.unpack_from("<I", out, at)[0]
    value = rng.choice(INTERESTING_INTS[:22] + [old + 1, old - 1, old * 2, old + 64])
    struct.pack_into("<I", out, at, value & 0xFFFFFFFF)
    return bytes(out)


def splatvq_payload(rng, data, name):
    """A .splatvq block's payload damaged inside (bytes changed, widths raised, cut or lengthened) and deflated
    again, its table entry made to agree (or not): the decoder's own checks, past the deflate layer."""
    parts = _splatvq_parts(data) if _is_splatvq(name) else None
    if parts is None or not parts[1]:
        return bit_flips(rng, data, name)
    json_len, blocks, table_at = parts
    entries = [list(splatvq.BLOCK_ENTRY.unpack_from(data, table_at + i * splatvq.BLOCK_ENTRY.size))
               for i in range(blocks) if table_at + (i + 1) * splatvq.BLOCK_ENTRY.size <= len(data)]
    body_at = table_at + blocks * splatvq.BLOCK_ENTRY.size
    if len(entries) != blocks or body_at + sum(e[3] for e in entries) != len(data):
        return bit_flips(rng, data, name)
    i = rng.randrange(blocks)
    start = body_at + sum(e[3] for e in entries[:i])
    try:
        payload = bytearray(zlib.decompress(data[start:start + entries[i][3]], -15))
    except zlib.error:
        return bit_flips(rng, data, name)
    coded = entries[i][0]
    widths_at = -(-coded // vq_codec.CHUNK) * vq_codec.CHUNK_BYTES
    choice = rng.randrange(4)
    if choice == 0 and payload:
        for _ in range(rng.randint(1, 6)):
            payload[rng.randrange(len(payload))] = rng.choice([0, 1, 3, 4, 5, 0x7F, 0xF3, 0xF4, 0xFE, 0xFF])
    elif choice == 1 and len(payload) >= widths_at + len(vq_codec.WIDTH_COLUMNS):
        payload[widths_at + rng.randrange(len(vq_codec.WIDTH_COLUMNS))] = rng.choice([0, 1, 2, 3, 4, 5, 255])
    elif choice == 2:
        del payload[rng.randrange(len(payload) + 1):]
    else:
        payload += bytes(rng.choice([1, 7, 64, 500]))
    deflate = zlib.compressobj(6, zlib.DEFLATED, -15)
    stored = deflate.compress(bytes(payload)) + deflate.flush()
    end = start + entries[i][3]
    if rng.random() < 0.8:
        entries[i][2] = len(payload)
    entries[i][3] = len(stored)
    table = b"".join(splatvq.BLOCK_ENTRY.pack(*e) for e in entries)
    return data[:table_at] + table + data[body_at:start] + stored + data[end:]


def huge_count(rng, data, name):
    """Counts that declare far more (or fewer, or negative) rows or texture than the file holds."""
    if _is_splatvq(name):
        return _splatvq_huge_count(rng, data)
    if name.lower().replace(".zst", "").endswith(".ply"):
        end = _header_len(data)
        head = data[:end]
        k = head.find(b"element vertex ")
        if k < 0:
            return data
        stop = head.find(b"\n", k)
        value = rng.choice([10**12, 2**31, 2**32 + 5, -3000, 0, 1, 19, 21, 39, 41, 10**30])
        return head[:k] + f"element vertex {value}".encode() + head[stop:] + data[end:]
    chunks_edit = rng.choice([("texheight", rng.choice(INTERESTING_INTS)), ("size", rng.choice(INTERESTING_INTS)),
                              ("count", rng.choice(INTERESTING_INTS)),
                              ("texwidth", rng.choice([0, 4095, 4096, 8192, 2**31]))])
    try:
        json_len = struct.unpack_from("<I", data, 4)[0]
        chunks = json.loads(data[8:8 + json_len])
        chunks[0][chunks_edit[0]] = chunks_edit[1]
        if chunks_edit[0] == "texheight" and rng.random() < 0.5:
            chunks[0]["size"] = 4096 * 16 * max(0, chunks_edit[1])
    except (ValueError, RecursionError, struct.error, IndexError, KeyError, TypeError):
        return data
    text = json.dumps(chunks).encode()
    return data[:4] + struct.pack("<I", len(text)) + text + data[8 + json_len:]


MUTATORS = {"bit_flips": bit_flips, "byte_values": byte_values, "truncate": truncate, "extend": extend,
            "header_edit": header_edit, "huge_count": huge_count, "splatvq_payload": splatvq_payload}


def _compress(rng, content: bytes, extra_zeros: int = 0) -> bytes:
    cctx = zstandard.ZstdCompressor(level=1, write_content_size=rng.random() < 0.5)
    out = []

    class _Sink:
        def write(self, b):
            out.append(bytes(b))
            return len(b)

    size = len(content) + extra_zeros
    with cctx.stream_writer(_Sink(), size=size, closefd=False) as z:
        z.write(content)
        block = bytes(1 << 20)
        for start in range(0, extra_zeros, len(block)):
            z.write(block[: min(len(block), extra_zeros - start)])
    return b"".join(out)


def mutant(rng: random.Random, seeds: dict, index: int | None = None) -> tuple:
    """One mutant: ``(file name, bytes, description)``; ``seeds`` maps names to contents.

    Mutant ``index`` takes the seed files in turn (a campaign reaches each as often); without it, one at random.
    """
    name = sorted(seeds)[index % len(seeds)] if index is not None else rng.choice(sorted(seeds))
    data = seeds[name]
    compressed = name.endswith(".zst")
    if compressed:
        data = zstandard.ZstdDecompressor().decompressobj().decompress(data)
    if compressed and rng.random() < 0.3:
        # A zstd bomb: a (maybe edited) header, then far more zeros than it declares.
        head = data[:_header_len(data)]
        if rng.random() < 0.5:
            head = huge_count(rng, head + data[len(head):], name)[:_header_len(data) + 64]
        zeros = rng.choice([2 << 20, 40 << 20, 70 << 20, 200 << 20])
        return name, _compress(rng, head, zeros), f"zstd bomb ({zeros >> 20} MiB of zeros)"
    kinds = rng.sample(sorted(MUTATORS), rng.choice([1, 1, 1, 2]))
    for kind in kinds:
        data = MUTATORS[kind](rng, data, name)
    if compressed:
        packed = _compress(rng, data)
        if rng.random() < 0.2:
            packed = bit_flips(rng, packed, name)
            kinds.append("zstd bit_flips")
        return name, packed, "+".join(kinds)
    return name, data, "+".join(kinds)


# --------------------------------------------------------------------------
# Running and checking


@dataclasses.dataclass
class Outcome:
    """What one mutant did."""

    index: int
    name: str
    kind: str
    seconds: float
    traced_peak: int
    exit_codes: list
    problems: list


def _commands(path: str, work: str) -> list:
    """Every command run on a mutant, and the output file each writes (None: writes none)."""
    out = functools.partial(os.path.join, work)
    converts = [(["convert", path, out(name)], out(name))
                for name in ("out.splatv", "out.ply", "out.splat", "out.html", "out.splatvq")]
    return [(["info", path], None), (["info", "--json", path], None), (["stats", path, "--zstd-level", "1"], None),
            *converts, (["bake", path, out("moment.ply"), "--time", "0.5"], out("moment.ply")),
            (["render", path, out("frame.png"), "--size", "32x18", "--time", "0.5"], out("frame.png")),
            (["diff", path, path, "--size", "32x18", "--times", "0.5"], None)]


def _check(result, args, problems: list) -> None:
    where = " ".join(args[:1] + args[1:2])
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        problems.append(f"{where}: exception {type(result.exception).__name__}: {result.exception}")
        return
    if "Traceback" in result.output:
        problems.append(f"{where}: traceback in output")
    if result.exit_code not in (0, 1):
        problems.append(f"{where}: exit {result.exit_code}: {result.stderr.strip()[:300]}")
    lines = result.stderr.splitlines()
    others = [line for line in lines if not line.startswith("note: ")]
    if result.exit_code == 1 and (len(others) != 1 or not others[0].startswith("Error: ")):
        problems.append(f"{where}: exit 1 without exactly one Error line: {result.stderr.strip()[:300]!r}")
    if result.exit_code == 0 and others:
        problems.append(f"{where}: success with stray stderr: {result.stderr.strip()[:300]!r}")


def run_mutant(index: int, name: str, data: bytes, kind: str, work: str, tmp: str) -> Outcome:
    """Run every command on one mutant and check what it left; ``tmp`` is the temporary folder in use."""
    path = os.path.join(work, name)
    with open(path, "wb") as f:
        f.write(data)
    digest = hashlib.sha256(data).digest()
    problems, codes = [], []
    runner = CliRunner()
    tracemalloc.reset_peak()
    start = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for args, out in _commands(path, work):
            result = runner.invoke(main, args)
            codes.append(result.exit_code)
            _check(result, args, problems)
            if out is not None:
                if os.path.exists(out) != (result.exit_code == 0):
                    problems.append(f"convert {os.path.basename(out)}: exit {result.exit_code} but output "
                                    f"{'exists' if os.path.exists(out) else 'missing'}")
                with contextlib.suppress(FileNotFoundError):
                    os.unlink(out)
    seconds = time.perf_counter() - start
    peak = tracemalloc.get_traced_memory()[1]
    for w in caught:
        problems.append(f"warning: {w.category.__name__}: {w.message}")
    left = sorted(set(os.listdir(work)) - {name}) + sorted(os.listdir(tmp))
    if left:
        problems.append(f"left behind: {left}")
        for leftover in os.listdir(tmp):
            os.unlink(os.path.join(tmp, leftover))
    with open(path, "rb") as f:
        if hashlib.sha256(f.read()).digest() != digest:
            problems.append("input changed")
    os.unlink(path)
    for extra in set(os.listdir(work)):
        os.unlink(os.path.join(work, extra))
    if seconds > MAX_SECONDS:
        problems.append(f"took {seconds:.1f} s (bound {MAX_SECONDS:.0f} s)")
    if peak > MAX_TRACED_BYTES:
        problems.append(f"traced memory peak {peak >> 20} MiB (bound {MAX_TRACED_BYTES >> 20} MiB)")
    return Outcome(index, name, kind, seconds, peak, codes, problems)


@contextlib.contextmanager
def campaign_environment(folder):
    """A private temporary folder, the campaign's decompression ceiling and memory tracing, for a campaign."""
    tmp = os.path.join(folder, "tmp")
    os.makedirs(tmp, exist_ok=True)
    saved_tempdir, saved_env = tempfile.tempdir, os.environ.get("SPLATCONV_MAX_DECOMPRESSED")
    tempfile.tempdir = tmp
    os.environ["SPLATCONV_MAX_DECOMPRESSED"] = CAMPAIGN_MAX_DECOMPRESSED
    tracing = tracemalloc.is_tracing()
    if not tracing:
        tracemalloc.start()
    try:
        yield tmp
    finally:
        if not tracing:
            tracemalloc.stop()
        tempfile.tempdir = saved_tempdir
        if saved_env is None:
            os.environ.pop("SPLATCONV_MAX_DECOMPRESSED", None)
        else:
            os.environ["SPLATCONV_MAX_DECOMPRESSED"] = saved_env


def campaign(folder, seed: int, count: int, on_outcome=None) -> list:
    """Run ``count`` mutants made with ``random.Random(seed)``; returns every :class:`Outcome`."""
    folder = os.fspath(folder)
    seed_dir = os.path.join(folder, "seeds")
    work = os.path.join(folder, "work")
    os.makedirs(seed_dir, exist_ok=True)
    os.makedirs(work, exist_ok=True)
    with campaign_environment(folder) as tmp:
        seeds = {}
        for p in make_seeds(seed_dir):
            with open(p, "rb") as f:
                seeds[os.path.basename(p)] = f.read()
        rng = random.Random(seed)
        outcomes = []
        for index in range(count):
            name, data, kind = mutant(rng, seeds, index)
            outcome = run_mutant(index, name, data, kind, work, tmp)
            if outcome.problems:
                with open(os.path.join(folder, f"failing-{index}-{name}"), "wb") as f:
                    f.write(data)
            outcomes.append(outcome)
            if on_outcome is not None:
                on_outcome(outcome)
    return outcomes
