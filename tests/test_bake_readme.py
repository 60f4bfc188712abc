"""The README's bake, .splat and merge commands run, and its bake picture is theirs.

Run as ``python -m tests.test_bake_readme`` to regenerate ``docs/bake_moment.png``.
"""

from __future__ import annotations

import os
import re
import shlex
import sys
import tempfile
from pathlib import Path

import numpy as np
from click.testing import CliRunner
from PIL import Image

from splatconv.cli import main
from splatconv.render.diff import compare, side_by_side

ROOT = Path(__file__).resolve().parent.parent
PICTURE = ROOT / "docs" / "bake_moment.png"


def section(title: str) -> str:
    text = (ROOT / "README.md").read_text()
    return text.split(title, 1)[1].split("\n### ", 1)[0].split("\n## ", 1)[0]


def commands(text: str) -> list:
    """The splatconv lines of a section's code blocks, in order."""
    blocks = re.findall(r"```\n(.*?)```", text, re.S)
    return [line for block in blocks for line in block.strip().splitlines() if line.startswith("splatconv ")]


def run_line(line: str):
    result = CliRunner().invoke(main, shlex.split(line)[1:])
    assert result.exit_code == 0, (line, result.output)
    return result


def make_picture(workdir: Path) -> np.ndarray:
    """Run the bake section's commands in ``workdir`` (which holds ``dancers.splatv``); the picture, RGB."""
    for line in commands(section("### Bake a moment")):
        run_line(line)
    left = np.asarray(Image.open(workdir / "4d.png").convert("RGB"))
    right = np.asarray(Image.open(workdir / "baked.png").convert("RGB"))
    return side_by_side(left, right)


def _sample(workdir: Path) -> None:
    os.symlink(ROOT / "sample_data", workdir / "sample_data")
    run_line("splatconv convert sample_data/dancers.ply dancers.splatv --cameras sample_data/cameras.json")


def test_bake_section_commands_and_picture(monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)
    _sample(tmp_path)
    made = make_picture(tmp_path)
    assert sorted(p.name for p in (tmp_path / "flipbook").iterdir())[::29] == ["frame_0000.ply", "frame_0029.ply"]
    shown = np.asarray(Image.open(PICTURE).convert("RGB"))
    assert compare(made, shown).psnr >= 40
    # The two halves are the same moment: the baked scene drawn at another time matches the 4D scene.
    half = (made.shape[1] - 4) // 2
    assert compare(made[:, :half], made[:, half + 4:]).psnr >= 40


def test_bake_section_python_example(monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)
    _sample(tmp_path)
    code = re.search(r"```python\n(.*?)```", section("### Bake a moment"), re.S).group(1)
    namespace = {}
    exec(compile(code, "README.md", "exec"), namespace)  # noqa: S102  (the README's own example)
    assert namespace["both"].count == 5_000 + namespace["moment"].count
    assert (tmp_path / "moment.splat").stat().st_size == 32 * namespace["moment"].count


def test_merge_section_commands(monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)
    _sample(tmp_path)
    lines = commands(section("### Compose scenes: merge"))
    assert lines and lines[-1].startswith("splatconv merge ")
    for line in lines:
        run_line(line)


if __name__ == "__main__":
    with tempfile.TemporaryDirectory() as tmp:
        os.chdir(tmp)
        _sample(Path(tmp))
        Image.fromarray(make_picture(Path(tmp))).save(PICTURE)
    print(f"wrote {PICTURE}", file=sys.stderr)
