"""Peak memory of commands on small files that expand a lot (decompression bombs).

A few hundred kilobytes of zstd can hold gigabytes of zeros, a valid scene;
a ``.splatvq`` of blocks of zero codes declares 65,536 splats in 1.5 KB.
Each command runs in a fresh process (``_harness.run_fresh``: peak RSS from
``os.wait4``) under the ceiling ``--max-decompressed`` (``--ceiling``):

* a ``.splat.zst`` and a ``.splatv.zst`` of ``--bytes`` decompressed bytes;
* a ``.splatvq`` (and its ``.zst``) declaring ``--splats`` splats (18.5 million:
  what the 2 GiB ceiling let through at 116 bytes a splat): ``info``'s peak RSS and
  time (it reads a block at a time), and ``convert``'s (refused at once);
* a ``.splatvq`` declaring the most splats the ceiling lets ``convert`` hold
  (ceiling / 192 bytes), converted to ``.ply`` and ``.splatv``: its peak RSS as a
  ratio of the ceiling (at most 1.25);
* a row per whole-scene command (``stats`` of one file and of two, ``verify``,
  ``diff``, ``render``, ``bake``, ``merge``, ``convert``) on a drawable scene
  (``.splatv.zst``; ``.splatvq`` for ``stats`` of one file, which encodes it at
  every quality) of the most splats it admits: its peak RSS as a ratio of the
  ceiling.

    python bench/bench_memory.py                      # 1.8 GB bombs, default ceiling
    python bench/bench_memory.py --bytes 480M --ceiling 512M --splats 4600000
"""

from __future__ import annotations

import argparse
import json
import os
import struct
import sys

import zstandard

from _harness import CLI, machine_line, row, run_fresh, work_folder

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
from splatconv import io, stats  # noqa: E402
from splatconv.io import SPLAT_MEMORY_BYTES  # noqa: E402
from splatconv.jobs import bake, convert, merge  # noqa: E402
from splatconv.render import commands, verify  # noqa: E402
from tests.scenes import moving_scene  # noqa: E402
from splatconv.formats.splatvq_codec import BLOCK  # noqa: E402
from splatconv.zstd import DEFAULT_MAX_DECOMPRESSED, parse_byte_size  # noqa: E402
from tests.splatvq_files import declaring  # noqa: E402

TEXEL_ROW = 4096 * 16  # bytes of one .splatv texture row (1,024 splats)
#: One drawable splat, repeated: a bomb of real splats, not of padding.
SPLAT_RECORD = struct.pack("<3f3f4B4B", 0, 0, 0, 0.1, 0.1, 0.1, 200, 100, 50, 255, 255, 128, 128, 128)
SPLATV_RECORD = struct.pack("<3f", 0, 0, 0) + bytes([60] * 52)


def bomb(path: str, head: bytes, record: bytes, count: int) -> str:
    """``head`` then ``count`` copies of ``record``, zstd-compressed as one frame that declares its size."""
    with open(path, "wb") as f, \
            zstandard.ZstdCompressor(level=3).stream_writer(f, size=len(head) + count * len(record)) as z:
        z.write(head)
        step = (1 << 22) // len(record)
        block = record * step
        for start in range(0, count, step):
            z.write(block[: min(step, count - start) * len(record)])
    return path


def splatv_head(rows: int) -> bytes:
    text = json.dumps([{"type": "splat", "size": TEXEL_ROW * rows, "texwidth": 4096, "texheight": rows,
                        "cameras": []}]).encode()
    return struct.pack("<II", 0x674B, len(text)) + text


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bytes", default="1800000000", help="decompressed bytes of each bomb (default 1.8 GB)")
    ap.add_argument("--ceiling", default=None, help="--max-decompressed for the commands (default: the default)")
    ap.add_argument("--splats", type=int, default=18_500_000, help=".splatvq splats declared (default 18.5 M)")
    ap.add_argument("--keep", default=None, help="work folder to keep")
    args = ap.parse_args()
    size = parse_byte_size(args.bytes)
    ceiling = ["--max-decompressed", args.ceiling] if args.ceiling else []
    print(machine_line(load=True))
    print(f"bombs of {size:,} decompressed bytes; ceiling {args.ceiling or 'default (2 GiB)'}")
    with work_folder(args.keep) as folder:
        rows = size // TEXEL_ROW
        files = {
            "splat": bomb(os.path.join(folder, "bomb.splat.zst"), b"", SPLAT_RECORD, size // len(SPLAT_RECORD)),
            "splatv": bomb(os.path.join(folder, "bomb.splatv.zst"), splatv_head(rows), SPLATV_RECORD,
                           rows * TEXEL_ROW // len(SPLATV_RECORD)),
        }
        for kind, path in files.items():
            print(f"{kind}: {os.path.getsize(path):,} bytes compressed")
            for command in (["info", path], ["convert", path, os.path.join(folder, "out.ply"), "--force"]):
                measure(ceiling, command, kind)
        limit = parse_byte_size(args.ceiling) if args.ceiling else DEFAULT_MAX_DECOMPRESSED
        vq = splatvq_file(os.path.join(folder, "declares.splatvq"), args.splats)
        print(f"splatvq: {os.path.getsize(vq):,} bytes ({os.path.getsize(vq + '.zst'):,} as .zst) declaring "
              f"{args.splats:,} splats ({args.splats * SPLAT_MEMORY_BYTES / limit:.2f} x the ceiling at "
              f"{SPLAT_MEMORY_BYTES} bytes a splat)")
        for path, kind in ((vq, "splatvq"), (vq + ".zst", "splatvq.zst")):
            measure(ceiling, ["info", path], kind)
            measure(ceiling, ["convert", path, os.path.join(folder, "out.ply"), "--force"], kind, limit)
        most = limit // convert.CONVERT_MEMORY_BYTES
        full = splatvq_file(os.path.join(folder, "full.splatvq"), most)
        print(f"splatvq: {os.path.getsize(full):,} bytes declaring {most:,} splats, the most the ceiling lets a "
              "command hold")
        measure(ceiling, ["convert", full, os.path.join(folder, "out.ply"), "--force"], "splatvq", limit)
        measure(ceiling, ["convert", full, os.path.join(folder, "out.splatv"), "--force"], "splatvq -> splatv",
                limit)
        print("each command on a drawable scene of the most splats it admits (bytes a splat it counts):")
        for name, (each, reads) in COMMANDS.items():
            n = limit // each // reads // 1024 * 1024  # a .splatv holds whole texture rows
            base = run_fresh([CLI, *ceiling, *command_line(name, scene_files(folder, 2 * BLOCK // reads,
                                                                             name == "stats"), folder)])
            r = run_fresh([CLI, *ceiling, *command_line(name, scene_files(folder, n, name == "stats"), folder)])
            outcome = "ok" if r["code"] == 0 else r["stderr"].strip().splitlines()[-1][:60]
            print(row(f"  {name} {n:,} x {reads} ({each} B)", f"{r['rss_mb'] / 1000:.2f} GB peak RSS",
                      f"{r['rss_mb'] * 1e6 / limit:.2f} x ceiling; over a run on 2 blocks' splats "
                      f"{(r['rss_mb'] - base['rss_mb']) * 1e6 / limit:.2f} x, exit {r['code']}: {outcome}"))


def command_line(name: str, files: tuple, folder: str) -> list:
    """The command line of the whole-scene command ``name`` on ``files`` (:func:`scene_files`)."""
    vq, a, b = files
    out = os.path.join(folder, "cmd")
    pictures = ["--size", "64x64"]
    return {"stats": ["stats", vq], "stats-pair": ["stats", a, b],
            "verify": ["verify", a, b, "--times", "0.5", "--cameras", "0", *pictures],
            "diff": ["diff", a, b, "--reference", *pictures],
            "render": ["render", a, out + ".png", "--reference", "--force", *pictures],
            "bake": ["bake", a, out + ".ply", "--time", "0.5", "--force"],
            "merge": ["merge", a, b, out + ".splatv", "--force"],
            "convert": ["convert", a, out + ".splatvq", "--force"]}[name]


#: Each whole-scene command: the bytes a splat read takes at its peak, as it counts them, and the scenes it reads.
COMMANDS = {"stats": (stats.STATS_MEMORY_BYTES, 1), "stats-pair": (stats.STATS_PAIR_MEMORY_BYTES, 2),
            "verify": (verify.VERIFY_MEMORY_BYTES, 2), "diff": (verify.DIFF_MEMORY_BYTES, 2),
            "render": (commands.RENDER_MEMORY_BYTES, 1), "bake": (bake.BAKE_MEMORY_BYTES, 1),
            "merge": (merge.MERGE_MEMORY_BYTES, 2), "convert": (convert.CONVERT_MEMORY_BYTES, 1)}


def scene_files(folder: str, n: int, splatvq: bool) -> tuple:
    """A drawable scene of ``n`` splats: as ``.splatvq`` (if asked), as ``.splatv.zst`` and a copy of that."""
    scene = moving_scene(n)
    vq, a, b = (os.path.join(folder, f"scene{n}{suffix}") for suffix in (".splatvq", ".splatv.zst", "-b.splatv.zst"))
    if splatvq and not os.path.exists(vq):
        io.write(scene, vq)
    if not os.path.exists(a):
        io.write(scene, a)
        with open(a, "rb") as f, open(b, "wb") as g:
            g.write(f.read())
    return vq, a, b


def measure(ceiling: list, command: list, kind: str, limit: int | None = None) -> None:
    """Run ``splatconv [ceiling] command`` fresh and print its peak RSS (as a share of ``limit`` if given)."""
    r = run_fresh([CLI, *ceiling, *command])
    outcome = "ok" if r["code"] == 0 else r["stderr"].strip().splitlines()[-1].split(": ", 2)[-1][:60]
    ratio = f" ({r['rss_mb'] * 1e6 / limit:.2f} x ceiling)" if limit else ""
    print(row(f"  {command[0]} {kind}", f"{r['rss_mb'] / 1000:.2f} GB peak RSS",
              f"{r['wall']:.1f} s{ratio}, exit {r['code']}: {outcome}"))


def splatvq_file(path: str, splats: int) -> str:
    """A ``.splatvq`` of blocks of zero codes declaring ``splats`` (and its ``.zst`` beside it)."""
    blocks = -(-splats // BLOCK)
    data = declaring(blocks, splats - (blocks - 1) * BLOCK)
    with open(path, "wb") as f:
        f.write(data)
    with open(path + ".zst", "wb") as f:
        f.write(zstandard.ZstdCompressor(level=19).compress(data))
    return path


if __name__ == "__main__":
    main()
