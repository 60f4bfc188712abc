"""The commands' jobs (splatconv.jobs) and the atomic output they write through (splatconv.files.output)."""

from __future__ import annotations

import os

import pytest
from click.testing import CliRunner

from splatconv.cli import main
from splatconv.files import output as atomic_output


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def test_a_group_that_cannot_put_a_file_in_place_names_the_output_and_leaves_nothing(tmp_path, monkeypatch):
    """One atomic core for one file and for a group: a failed rename names the output, not its part file."""
    real = os.replace

    def refuse(src, dst):
        raise PermissionError(13, "Permission denied", src, dst)

    monkeypatch.setattr(atomic_output.os, "replace", refuse)
    for count in (1, 2):
        outputs = [tmp_path / f"out{count}_{k}.bin" for k in range(count)]
        with pytest.raises(PermissionError) as caught:
            with atomic_output.atomic_group() as group:
                for out in outputs:
                    with group.open(out) as f:
                        f.write(b"data")
        assert caught.value.filename == str(outputs[0]) and caught.value.filename2 is None
        with pytest.raises(PermissionError) as caught:
            with atomic_output.atomic_writer(outputs[0]) as f:
                f.write(b"data")
        assert caught.value.filename == str(outputs[0]) and caught.value.filename2 is None
    monkeypatch.setattr(atomic_output.os, "replace", real)
    assert sorted(p.name for p in tmp_path.iterdir()) == []


@pytest.mark.parametrize("command", [["bake", "--time", "0.5"], ["merge", "other.ply"]])
def test_bake_and_merge_check_the_inputs_format_first_as_convert_does(tmp_path, monkeypatch, command):
    """Every job takes its checks in one order: the inputs' formats, the output's options, the output path."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "scene.xyz").write_bytes(b"not a scene")
    (tmp_path / "other.ply").write_bytes(b"")
    (tmp_path / "out.ply").write_bytes(b"old")
    expected = run("convert", "scene.xyz", "out.ply")
    assert expected.exit_code in (1, 2) and "already exists" not in expected.stderr
    name, *options = command
    got = run(name, "scene.xyz", *options, "out.ply")
    assert (got.exit_code, got.stderr) == (expected.exit_code, expected.stderr)
    assert (tmp_path / "out.ply").read_bytes() == b"old"
