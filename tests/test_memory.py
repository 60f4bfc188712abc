"""Memory under the decompression ceiling: ``info`` holds a block at a time, a scene read holds what the check counts.

A ``.splatvq`` of blocks of zero codes is a few kilobytes a block and declares 65,536 splats each
(:func:`tests.splatvq_files.declaring`). Bounds are derived from the block and the scene's table, never
from the machine's speed: the figures compared are the growth in peak memory between a file of a few
blocks and one of many, which leaves out the interpreter, numpy and the decoders' per-block work.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tracemalloc

import pytest

from splatconv import io
from splatconv.formats import splatvq
from splatconv.formats import splatvq_codec as codec

from .splatvq_files import declaring

FEW, MANY = 4, 16


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("memory")
    out = {}
    for blocks in (FEW, MANY):
        out[blocks] = folder / f"b{blocks}.splatvq"
        out[blocks].write_bytes(declaring(blocks))
    return out


#: Runs argv[1:] and prints its exit code and ru_maxrss (KiB) last. A child's ru_maxrss starts from the
#: RSS of the process that started it (Linux carries it across fork and exec): a small launcher keeps
#: the test process's own memory out of the figure.
_LAUNCHER = """\
import os, subprocess, sys
p = subprocess.Popen(sys.argv[1:])
_, status, usage = os.wait4(p.pid, 0)
sys.stdout.flush()
print(os.waitstatus_to_exitcode(status), usage.ru_maxrss)
"""


def _peak_rss(args) -> tuple[int, subprocess.CompletedProcess]:
    """Run the CLI in a fresh child; its peak RSS in bytes and its exit code, output and errors."""
    r = subprocess.run([sys.executable, "-c", _LAUNCHER, sys.executable, "-m", "splatconv", *map(str, args)],
                       capture_output=True, check=True)
    out, _, last = r.stdout.rstrip(b"\n").rpartition(b"\n")
    code, maxrss = map(int, last.split())
    return maxrss * 1024, subprocess.CompletedProcess(r.args, code, out, r.stderr)


def test_info_holds_a_block_at_a_time_not_the_scene(files):
    """A 100 KB file declaring a million splats: info's peak memory does not grow with the splats (it
    grew by their records and table, 192 bytes a splat), even under a ceiling below the scene's table."""
    ceiling = ["--max-decompressed", "64M"]
    few, r_few = _peak_rss([*ceiling, "info", "--json", files[FEW]])
    many, r_many = _peak_rss([*ceiling, "info", "--json", files[MANY]])
    assert r_many.returncode == 0, r_many.stderr
    assert json.loads(r_many.stdout)["count"] == MANY * codec.BLOCK
    assert os.path.getsize(files[MANY]) < 150_000
    # The scene's records and table would grow by (MANY - FEW) * 65,536 * 192 bytes (151 MB here); a block's decoding is
    # the same for both files. Allow 6 blocks' table (50 MB) for the allocator's arenas warming up.
    assert many - few < 6 * codec.BLOCK * io.SPLAT_MEMORY_BYTES


def test_a_whole_scene_command_is_refused_at_once_under_the_ceiling(files, tmp_path):
    out = tmp_path / "out.ply"
    peak, r = _peak_rss(["--max-decompressed", "64M", "convert", files[MANY], out])
    assert r.returncode == 1 and r.stderr.decode().startswith(
        f"Error: {files[MANY]}: holds {MANY * codec.BLOCK:,} splats: up to "
        f"{MANY * codec.BLOCK * io.SPLAT_MEMORY_BYTES:,} bytes in memory")
    assert "--max-decompressed" in r.stderr.decode()
    assert not out.exists()
    # Refused before a block is decoded: the interpreter's own memory, not the scene's table.
    assert peak < MANY * codec.BLOCK * io.SPLAT_MEMORY_BYTES / 2


def _traced_peak(fn) -> int:
    tracemalloc.start()
    try:
        fn()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def test_a_read_holds_the_table_the_ceiling_counts(files):
    """The check counts io.SPLAT_MEMORY_BYTES a splat: reading the scene whole allocates that (its table)
    and a block or two in flight, not the records besides (64 bytes a splat more, once)."""
    scene = splatvq.read(files[FEW])
    table = scene.columns["x"].base
    assert table.nbytes == scene.count * io.SPLAT_MEMORY_BYTES
    del scene, table
    few = _traced_peak(lambda: splatvq.read(files[FEW]))
    many = _traced_peak(lambda: splatvq.read(files[MANY]))
    extra = (MANY - FEW) * codec.BLOCK
    # Exactly the table's growth (numpy's allocations are traced, whatever the allocator keeps).
    assert many - few < 1.05 * extra * io.SPLAT_MEMORY_BYTES
