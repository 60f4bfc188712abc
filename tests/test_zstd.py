"""zstd transport: .zst output, and .zst input read transparently by every command."""

from __future__ import annotations

import json

import zstandard
from click.testing import CliRunner

from splatconv.cli import main


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
    assert r.stderr == (f"Error: {bad}: not a valid zstd stream (zstd decompressor error: Unknown frame "
                        "descriptor)\n")


def test_errors_inside_a_zst_name_the_zst_file(tmp_path):
    bad = tmp_path / "inner.splatv.zst"
    bad.write_bytes(zstandard.compress(b"\x00" * 20))
    r = run("info", bad)
    assert r.exit_code == 1
    assert r.stderr == f"Error: {bad}: not a .splatv file: magic 0x00000000, expected 0x0000674b\n"
    assert not list(tmp_path.glob("splatconv-*"))
