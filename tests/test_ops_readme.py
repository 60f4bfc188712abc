"""The README's editing examples run, and print what the README shows."""

from __future__ import annotations

import os
import re
import shlex
from pathlib import Path

from click.testing import CliRunner

from splatconv.cli import main

ROOT = Path(__file__).resolve().parent.parent
SECTION = re.split(r"\n##+ ", (ROOT / "README.md").read_text().split("### Editing while converting", 1)[1])[0]


def examples() -> list:
    """(command line, the output shown under it) for each ``$ splatconv`` block of the section."""
    out = []
    for block in re.findall(r"```\n(.*?)```", SECTION, re.S):
        lines = block.splitlines()
        assert lines[0].startswith("$ splatconv "), block
        out.append((lines[0][2:], lines[1:]))
    return out


def test_editing_examples_run_and_print_what_is_shown(tmp_path, monkeypatch):
    os.symlink(ROOT / "sample_data", tmp_path / "sample_data")
    monkeypatch.chdir(tmp_path)
    found = examples()
    assert len(found) == 3
    for line, shown in found:
        result = CliRunner().invoke(main, shlex.split(line)[1:])
        assert result.exit_code == 0, result.output
        if shown:
            assert result.stderr.splitlines() + result.stdout.splitlines() == shown
