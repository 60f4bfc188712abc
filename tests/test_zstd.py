"""zstd transport: .zst output, and .zst input read transparently by every command."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest
import zstandard
from click.testing import CliRunner

from splatconv.cli import main

from .conftest import ProgressRecorder


def unzstd(path) -> bytes:
    return zstandard.ZstdDecompressor().decompressobj().decompress(path.read_bytes())


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def test_zst_output_is_the_plain_file_compressed(tmp_path, lite_ply):
    plain, packed = tmp_path / "a.splatv", tmp_path / "a.splatv.zst"
    assert run("convert", lite_ply, plain).exit_code == 0
    r = run("convert", lite_ply, packed, "--zstd-level", "3")
    assert r.exit_code == 0, r.output
    assert unzstd(packed) == plain.read_bytes()
    assert packed.stat().st_size < plain.stat().st_size


def test_every_command_reads_zst_input(tmp_path, lite_ply):
    packed = tmp_path / "s.splatv.zst"
    assert run("convert", lite_ply, packed, "--zstd-level", "1").exit_code == 0
    info = json.loads(run("info", packed, "--json").stdout)
    assert info["count"] == 3000 and info["compressed_bytes"] == packed.stat().st_size
    assert run("convert", packed, tmp_path / "back.ply").exit_code == 0
    assert run("convert", tmp_path / "back.ply", tmp_path / "back.ply.zst", "--zstd-level", "1").exit_code == 0
    assert json.loads(run("info", tmp_path / "back.ply.zst", "--json").stdout)["variant"] == "Spacetime Gaussians lite"
    assert run("render", packed, tmp_path / "f.png", "--size", "32x18").exit_code == 0
    r = run("verify", lite_ply, packed, "--size", "64x36", "--times", "0.5")
    assert r.exit_code == 0, r.output
    data = json.loads(run("stats", lite_ply, packed, "--json", "--zstd-level", "1").stdout)
    assert data["files"][1]["path"] == str(packed)
    assert data["files"][1]["bytes"] == len(unzstd(packed))  # sizes are of the content


def test_bad_zst_input(tmp_path):
    bad = tmp_path / "bad.splatv.zst"
    bad.write_bytes(b"not zstd at all")
    r = run("info", bad)
    assert r.exit_code == 1
    assert r.stderr == f"Error: {bad}: not a valid zstd stream (Unknown frame descriptor)\n"


def test_errors_inside_a_zst_name_the_zst_file(tmp_path):
    bad = tmp_path / "inner.splatv.zst"
    bad.write_bytes(zstandard.compress(b"\x00" * 20))
    r = run("info", bad)
    assert r.exit_code == 1
    assert r.stderr == f"Error: {bad}: not a .splatv file: magic 0x00000000, expected 0x0000674b\n"
    assert not list(tmp_path.glob("splatconv-*"))


def test_stats_of_zst_inputs_are_of_the_content(tmp_path, lite_ply):
    packed_ply, packed = tmp_path / "s.ply.zst", tmp_path / "s.splatv.zst"
    assert run("convert", lite_ply, packed_ply, "--zstd-level", "1").exit_code == 0
    assert run("convert", lite_ply, packed, "--zstd-level", "1").exit_code == 0
    data = json.loads(run("stats", packed_ply, packed, "--json", "--zstd-level", "9").stdout)
    for f, path in zip(data["files"], (packed_ply, packed)):
        content = unzstd(path)
        assert f["bytes"] == len(content)
        assert f["bytes_per_splat"] == round(len(content) / 3000, 3)
        # The content compressed again at the level asked for (one frame, one job at this size),
        # not the size of the file on disk, written at level 1.
        assert f["zstd_level"] == 9
        again = zstandard.ZstdCompressor(level=9, threads=-1, write_content_size=True).compress(content)
        assert f["zstd_bytes"] == len(again)
        assert f["zstd_bytes"] != path.stat().st_size
    src, out = data["files"]
    assert out["ratio"] == round(out["bytes"] / src["bytes"], 6)
    assert out["zstd_ratio"] == round(out["zstd_bytes"] / src["bytes"], 6)


def test_stats_decompresses_each_zst_input_once(tmp_path, lite_ply, monkeypatch):
    from splatconv import zstd

    packed_ply, packed = tmp_path / "s.ply.zst", tmp_path / "s.splatv.zst"
    assert run("convert", lite_ply, packed_ply, "--zstd-level", "1").exit_code == 0
    assert run("convert", lite_ply, packed, "--zstd-level", "1").exit_code == 0
    seen = []
    real = zstd._decompress
    monkeypatch.setattr(zstd, "_decompress", lambda f, out, path, *rest: (seen.append(path), real(f, out, path, *rest))[1])
    assert run("stats", packed_ply, packed, "--json").exit_code == 0
    assert sorted(seen) == sorted([str(packed_ply), str(packed)])


class _SpyWriter:
    """Wraps a zstd stream writer, recording the size of every write it is given."""

    def __init__(self, inner, sizes):
        self.inner, self.sizes = inner, sizes

    def write(self, data):
        self.sizes.append(memoryview(data).nbytes)
        return self.inner.write(data)

    def __enter__(self):
        self.inner.__enter__()
        return self

    def __exit__(self, *exc):
        return self.inner.__exit__(*exc)

    def close(self):
        return self.inner.close()


@pytest.fixture
def compressor_writes(monkeypatch):
    """Sizes of the writes every zstd stream writer made by splatconv.zstd receives."""
    from splatconv import zstd

    sizes, real = [], zstd.compressor

    class Spy:
        def __init__(self, level, size_hint=None):
            self.real = real(level, size_hint)

        def stream_writer(self, *args, **kwargs):
            return _SpyWriter(self.real.stream_writer(*args, **kwargs), sizes)

        def frame_progression(self):
            return self.real.frame_progression()

    monkeypatch.setattr(zstd, "compressor", Spy)
    return sizes


#: Splats of the streaming tests: an 18.75 MiB texture.
STREAM_SPLATS = 300 * 1024
#: Largest write the compressor may get: a small part of the texture.
MAX_WRITE = 2 << 20


def _big_scene():
    from splatconv.model import COLUMNS, Scene

    cols = {name: np.zeros(STREAM_SPLATS, np.float32) for name in COLUMNS}  # compresses fast
    cols["x"] = np.arange(STREAM_SPLATS, dtype=np.float32)
    return Scene(columns=cols)


def test_zst_output_is_compressed_as_it_is_written(tmp_path, compressor_writes):
    import splatconv

    out = tmp_path / "big.splatv.zst"
    splatconv.write(_big_scene(), out, zstd_level=1)
    content = unzstd(out)
    assert len(content) > STREAM_SPLATS * 64
    # Handed over in many small pieces, never the whole texture at once.
    assert sum(compressor_writes) == len(content)
    assert max(compressor_writes) <= MAX_WRITE
    assert len(compressor_writes) >= len(content) // MAX_WRITE


def test_sizes_are_measured_piece_by_piece(compressor_writes):
    from splatconv.zstd import compressed_bytes

    data = np.arange(STREAM_SPLATS * 16, dtype="<u4").tobytes()
    pieces = [data[i:i + MAX_WRITE] for i in range(0, len(data), MAX_WRITE)]
    packed = compressed_bytes(iter(pieces), len(data), 1)
    assert sum(compressor_writes) == len(data)
    assert max(compressor_writes) <= MAX_WRITE
    assert packed == pytest.approx(len(zstandard.ZstdCompressor(level=1).compress(data)), rel=0.05)




def test_compressing_and_decompressing_report_progress(tmp_path):
    # Finishing a .zst frame compresses what zstd's workers still hold (tens of seconds at level 19
    # for a big scene): a "compressing" stage follows "writing". Reading a .zst reports the
    # compressed bytes read; convert's read is a stage of its own. Each stage reaches its total.
    import splatconv

    packed = tmp_path / "big.splatv.zst"
    rec = ProgressRecorder()
    splatconv.write(_big_scene(), packed, zstd_level=3, progress=rec)
    assert [s[0] for s in rec.stages] == ["writing", "compressing"]
    assert all(done == total for _label, total, _unit, done in rec.stages), rec.stages
    assert rec.stages[1][2] == "byte" and 0 < rec.stages[1][1] <= len(unzstd(packed))

    rec = ProgressRecorder()
    splatconv.convert(packed, tmp_path / "back.ply", progress=rec)
    assert [s[:3] for s in rec.stages] == [["reading", 1, "file"],
                                          ["decompressing big.splatv.zst", packed.stat().st_size, "byte"],
                                          ["writing", STREAM_SPLATS, "splat"]]
    assert all(done == total for _label, total, _unit, done in rec.stages), rec.stages


# --------------------------------------------------------------------------
# zstd's highest levels and memory

#: Run in a child process: one conversion to .zst at level 1 (every module loaded, the allocator
#: warm), then the address space limited to what the process holds plus MARGIN bytes, then the
#: conversion at level 22, as the command line runs it.
_UNDER_A_LIMIT = """
import resource, sys
from splatconv.cli import main
src, warm, out, margin = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])
main(["convert", src, warm, "--zstd-level", "1", "--quiet"], standalone_mode=False)
with open("/proc/self/status") as f:
    held = next(int(line.split()[1]) for line in f if line.startswith("VmSize:")) * 1024
resource.setrlimit(resource.RLIMIT_AS, (held + margin, resource.RLIM_INFINITY))
sys.argv = ["splatconv", "convert", src, out, "--zstd-level", "22", "--quiet"]
main()
"""


@pytest.mark.skipif(not os.path.exists("/proc/self/status"), reason="reads the address space from /proc")
@pytest.mark.parametrize("margin_mib, written", [(512, True), (8, False)])
def test_level_22_takes_what_the_data_needs_or_says_so_in_one_line(tmp_path, lite_ply, margin_mib, written):
    """Level 22 took 640 MiB of context a worker whatever the data (3 GB of address space for a
    200 KB file was an "Allocation error" traceback): sized for the data it fits in 512 MiB more
    than the process holds; in 8 MiB more it is one Error line, and no file nor part file is left."""
    warm, out = tmp_path / "warm.splatv.zst", tmp_path / "out.splatv.zst"
    r = subprocess.run([sys.executable, "-c", _UNDER_A_LIMIT, str(lite_ply), str(warm), str(out),
                        str(margin_mib << 20)], capture_output=True, text=True, timeout=120,
                       env=dict(os.environ, OPENBLAS_NUM_THREADS="1"))
    assert "Traceback" not in r.stderr, r.stderr
    if written:
        assert r.returncode == 0, r.stderr
        assert unzstd(out) == unzstd(warm)
    else:
        assert r.returncode == 1
        errors = [line for line in r.stderr.splitlines() if not line.startswith("note: ")]
        assert len(errors) == 1 and errors[0].startswith(f"Error: {out}: zstd level 22 could not compress (") and \
            errors[0].endswith("; a lower --zstd-level needs less"), r.stderr
        assert sorted(p.name for p in tmp_path.iterdir()) == ["scene.ply", "warm.splatv.zst"]


def test_the_window_is_sized_for_the_data(tmp_path, lite_ply):
    """A .zst output's compressor is sized for about the file's bytes (the frame header's window), and
    the file's bytes never exceed that estimate by more than zstd's window covers."""
    from splatconv import io
    from splatconv.formats import REGISTRY

    from splatconv.ops.bake import bake

    scene = io.read(lite_ply)
    moment = bake(scene, 0.5)[0]
    for fmt in {f for f in REGISTRY.values() if f.write is not None}:
        suffix = fmt.suffixes[0]
        for layout in fmt.layouts or (None,):
            plain = tmp_path / f"s{suffix}"
            for written in (scene, moment):  # the moment for the static ones
                try:
                    io.write(written, plain, force=True, layout=layout)
                except io.UnsupportedError:
                    continue
                assert plain.stat().st_size <= io._size_hint(written), (suffix, layout)
    packed = tmp_path / "s.splatv.zst"
    io.write(scene, packed, zstd_level=22)
    window = zstandard.get_frame_parameters(packed.read_bytes()).window_size
    assert (tmp_path / "s.splatv").stat().st_size <= window <= 2 * io._size_hint(scene)
