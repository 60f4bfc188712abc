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

import numpy as np
import pytest

from splatconv import io
from splatconv.model import Scene
from splatconv.formats import splatvq
from splatconv.jobs import convert
from splatconv.formats import splatvq_codec as codec

from .splatvq_files import declaring

FEW, MANY = 4, 16
#: The blocks of the files of zero codes (:func:`files`).
BLOCKS = (FEW, MANY, 10)


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("memory")
    out = {}
    for blocks in BLOCKS:
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
    each = convert.CONVERT_MEMORY_BYTES
    assert r.returncode == 1 and r.stderr.decode().startswith(
        f"Error: {files[MANY]}: holds {MANY * codec.BLOCK:,} splats: up to "
        f"{MANY * codec.BLOCK * each:,} bytes in memory ({each} a splat)")
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


#: A ceiling low enough that the scenes are small and the runs quick. The interpreter, numpy, GL and the
#: work done a block of 65,536 splats at a time (two ``.splatvq`` blocks encoded at once: some 160 MB) are
#: left out by measuring the growth over a run on two blocks' splats (in one scene or two).
CEILING = 80 << 20
#: The splats a whole-scene command was let read under CEILING before each counted what it holds: the
#: scene's table, 128 bytes a splat.
TABLE_SPLATS = CEILING // io.SPLAT_MEMORY_BYTES
BASE = 2 * codec.BLOCK


def _command(name: str, files, out) -> list:
    """The command line of ``name`` on ``files`` (a ``.splatvq`` and two scene files, compressed or expanding)."""
    vq, a, b = files
    pictures = ["--size", "32x32"]
    return {
        "stats": ["stats", vq],
        "stats-pair": ["stats", a, b],
        "verify": ["verify", a, b, "--times", "0.5", "--cameras", "0", *pictures],
        "diff": ["diff", a, b, "--reference", *pictures],
        "render": ["render", a, out / "frame.png", "--reference", *pictures],
        "bake": ["bake", a, out / "moment.ply", "--time", "0.5"],
        "merge": ["merge", a, b, out / "merged.splatv"],
        "convert": ["convert", a, out / "scene.splatvq"],
    }[name]


#: Each command: the bytes a splat read takes at its peak, as it declares them, and the scenes it reads.
def _budgets():
    from splatconv import stats
    from splatconv.jobs import bake, convert, merge
    from splatconv.render import commands, verify
    return {"stats": (stats.STATS_MEMORY_BYTES, 1), "stats-pair": (stats.STATS_PAIR_MEMORY_BYTES, 2),
            "verify": (verify.VERIFY_MEMORY_BYTES, 2), "diff": (verify.DIFF_MEMORY_BYTES, 2),
            "render": (commands.RENDER_MEMORY_BYTES, 1), "bake": (bake.BAKE_MEMORY_BYTES, 1),
            "merge": (merge.MERGE_MEMORY_BYTES, 2), "convert": (convert.PROVE_MEMORY_BYTES, 1)}


@pytest.fixture(scope="module")
def scenes(tmp_path_factory):
    """``scenes(n)``: files of a drawable scene of ``n`` splats, made once each."""
    from .scenes import moving_scene
    folder = tmp_path_factory.mktemp("scenes")
    made = {}

    def files(n: int, splatvq: bool):
        key = (n, splatvq)
        if key not in made:
            # Splats a quarter of moving_scene's size: what a command holds does not depend on how much
            # of a frame a splat covers, but a proof's time does (llvmpipe fills large splats slowly).
            scene = moving_scene(n)
            scene = Scene({k: np.array(v) + np.float32(np.log(0.25)) if k.startswith("scale_") else v
                           for k, v in scene.columns.items()}, cameras=scene.cameras, variant=scene.variant)
            vq, a, b = folder / f"s{n}.splatvq", folder / f"a{n}.splatv.zst", folder / f"b{n}.splatv.zst"
            if splatvq and not vq.exists():
                io.write(scene, vq)
            if not a.exists():
                io.write(scene, a)
                b.write_bytes(a.read_bytes())
            made[key] = (vq, a, b)
        return made[key]
    return files


def _run(name, files, tmp_path):
    out = tmp_path / "out"
    out.mkdir(exist_ok=True)
    for old in out.iterdir():
        old.unlink()
    return _peak_rss(["--max-decompressed", str(CEILING), *_command(name, files, out)])


@pytest.mark.parametrize("name", ["stats", "stats-pair", "verify", "diff", "render", "bake", "merge", "convert"])
def test_a_whole_scene_command_stays_within_the_ceiling(name, scenes, files, tmp_path):
    """Each command, on the largest drawable scene it lets through, and on a ``.splatvq`` of as many splats as
    the scene's table fitted in the ceiling (what it let through before it counted what it holds), grows by at most 1.25 times the ceiling over a run on a scene of one block, or refuses
    the scene at once, naming --max-decompressed."""
    each, files_read = _budgets()[name]
    vq = name == "stats"
    # The base run on a scene the ceiling lets through with room (convert, proving its output, takes most).
    base, r = _run(name, scenes(min(BASE // files_read, CEILING // each // 2 // 1024 * 1024), vq), tmp_path)
    assert r.returncode == 0, r.stderr
    most = CEILING // each // files_read // 1024 * 1024  # a .splatv holds whole texture rows of 1,024
    peak, r = _run(name, scenes(most, vq), tmp_path)
    assert r.returncode == 0, r.stderr
    assert peak - base <= 1.25 * CEILING
    peak, r = _run(name, (files[TABLE_SPLATS // codec.BLOCK],) * 3, tmp_path)
    if r.returncode == 0:
        assert peak - base <= 1.25 * CEILING
    else:
        err = r.stderr.decode()
        assert r.returncode == 1 and err.startswith("Error: ") and "--max-decompressed" in err, err
        assert peak - base < CEILING / 4


THREADS_ALLOCATING = """
import ctypes, sys, threading
import numpy as np
from splatconv.files.heap import one_arena
print(one_arena())
def work():
    for _ in range(200):
        held = [np.ones(20000) for _ in range(10)]
threads = [threading.Thread(target=work) for _ in range(4)]
for t in threads:
    t.start()
for t in threads:
    t.join()
sys.stdout.flush()
ctypes.CDLL(None).malloc_stats()  # to stderr: a paragraph an arena
"""


@pytest.mark.parametrize("asked", [None, "8"])
def test_helper_threads_share_one_arena_unless_the_environment_says(asked):
    # The command line (splatconv.__main__.run) calls one_arena first: what a helper thread
    # frees, another phase allocates, instead of an arena of its own keeping it resident.
    env = {k: v for k, v in os.environ.items() if k != "MALLOC_ARENA_MAX"}
    if asked:
        env["MALLOC_ARENA_MAX"] = asked
    done = subprocess.run([sys.executable, "-c", THREADS_ALLOCATING], env=env, capture_output=True, text=True,
                          check=True)
    arenas = sum(line.startswith("Arena ") for line in done.stderr.splitlines())
    assert done.stdout.split() == (["True"] if asked is None else ["False"])
    assert arenas == 1 if asked is None else arenas > 1


def resident_of(path) -> int:
    """Bytes of ``path``'s mappings resident in this process (/proc/self/smaps)."""
    total, mine = 0, False
    with open("/proc/self/smaps") as f:
        for line in f:
            head = line.split()
            if "-" in head[0] and not head[0].endswith(":"):  # a mapping's line: address range, ..., path
                mine = len(head) > 5 and head[5] == str(path)
            elif mine and head[0] == "Rss:":
                total += int(head[1]) * 1024
    return total


def test_a_proof_holds_no_page_of_a_mapped_input_between_its_passes(tmp_path):
    # A proof reads its scene to pack the source's frames and at each candidate's write; in
    # between, a mapped input's pages are handed back (the decode and the draws never sit beside
    # them), and the next pass reads the same values again.
    from splatconv.files.paging import hand_back, populate

    from .scenes import moving_scene

    source = tmp_path / "s.ply"
    io.write(moving_scene(40_000, seed=2), source)
    scene = io.read(source)
    size = os.path.getsize(source)
    before = {name: np.array(column) for name, column in scene.columns.items()}
    populate(scene.columns["x"])
    assert resident_of(source) >= 0.9 * size
    hand_back(list(scene.columns.values()) + [np.zeros(3)])  # an array of no mapping is left alone
    assert resident_of(source) < 0.01 * size
    assert all(np.array_equal(scene.columns[name], column, equal_nan=True) for name, column in before.items())
    assert resident_of(source) >= 0.9 * size
    # A copy-on-write mapping's pages may hold this process's changes: those are kept.
    raw = tmp_path / "r.f32"
    raw.write_bytes(bytes(4 * 4096))
    changed = np.memmap(raw, np.float32, mode="c")[::2]
    changed[:] = 7.0
    hand_back([changed])
    assert (changed == 7.0).all()


HEAP_FREED = """
import sys
from splatconv.files.heap import trim
def rss():
    with open("/proc/self/status") as f:
        return next(int(line.split()[1]) for line in f if line.startswith("VmRSS:")) * 1024
held = [bytes(2048) for _ in range(50_000)]  # 100 MB of malloc blocks (each past Python's small-object pool)
kept = held[::100]  # one block in a hundred stays: what is freed lies between them, not only at the top
del held
before = rss()
trim()
print(before - rss())
"""


def test_trim_gives_the_heaps_freed_pages_back():
    # A proof trims the heap around each candidate's write: the pages its decode and draws freed
    # are not resident through the next encode.
    done = subprocess.run([sys.executable, "-c", HEAP_FREED], capture_output=True, text=True, check=True)
    assert int(done.stdout) > 50e6
