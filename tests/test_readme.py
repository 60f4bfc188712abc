"""The README's commands and printed examples are true."""

from __future__ import annotations

import os
import re
import shlex
from pathlib import Path

from click.testing import CliRunner

from splatconv.cli import main

ROOT = Path(__file__).resolve().parent.parent
README = (ROOT / "README.md").read_text()


def quick_start_commands() -> list:
    section = README.split("## Quick start", 1)[1]
    block = re.search(r"```\n(.*?)```", section, re.S).group(1)
    return block.strip().splitlines()


def splatconv_args(line: str) -> list:
    """The splatconv part of 'pip install ... && splatconv ...'."""
    part = line.split("&&", 1)[1].strip()
    words = shlex.split(part)
    assert words[0] == "splatconv"
    return words[1:]


def test_quick_start_has_two_commands_install_and_test():
    lines = quick_start_commands()
    assert len(lines) == 2
    assert lines[0].startswith("pip install . && splatconv convert sample_data/")
    assert lines[1] == "pip install '.[test]' && python -m pytest"


def test_quick_start_conversion_and_info_example(tmp_path):
    os.symlink(ROOT / "sample_data", tmp_path / "sample_data")
    os.chdir(tmp_path)
    args = splatconv_args(quick_start_commands()[0])
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 0, result.output
    example = re.search(r"\$ splatconv info (\S+)\n(.*?)```", README, re.S)
    result = CliRunner().invoke(main, ["info", example.group(1)])
    assert result.exit_code == 0
    assert result.stdout == example.group(2)


def test_verify_example_runs_and_passes(tmp_path):
    os.symlink(ROOT / "sample_data", tmp_path / "sample_data")
    os.chdir(tmp_path)
    block = README.split("### Proving a conversion", 1)[1]
    lines = [ln[2:] for ln in block.splitlines() if ln.startswith("$ splatconv ")]
    assert len(lines) == 2
    for line in lines:
        result = CliRunner().invoke(main, shlex.split(line)[1:])
        assert result.exit_code == 0, result.output
    assert result.stdout.rstrip().splitlines()[-1].startswith("PASS: 3 frames at or above 40 dB")
    example = block.split("$ splatconv verify", 1)[1].split("```", 1)[0].splitlines()[1:]
    # The table's shape and verdict are as printed; exact dB depend on the GL driver.
    assert example[0] == result.stdout.splitlines()[0]
    assert example[-1].startswith("PASS: 3 frames")


def test_stats_example(tmp_path):
    os.symlink(ROOT / "sample_data", tmp_path / "sample_data")
    os.chdir(tmp_path)
    assert CliRunner().invoke(main, splatconv_args(quick_start_commands()[0])).exit_code == 0
    block = README.split("$ splatconv stats ", 1)[1]
    command, printed = block.split("\n", 1)
    printed = printed.split("```", 1)[0]
    result = CliRunner().invoke(main, ["stats"] + shlex.split(command))
    assert result.exit_code == 0, result.output
    assert result.stdout == printed
