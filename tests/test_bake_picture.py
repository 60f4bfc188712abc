"""docs/bake_moment.png (docs/bake-and-merge.md) is what its commands draw, and the bake example's library calls.

The page's commands themselves run in tests/test_docs.py; the picture is two of their frames side by side.
Run as ``python -m tests.test_bake_picture`` to regenerate ``docs/bake_moment.png``.
"""

from __future__ import annotations

import os
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


#: The commands of docs/bake-and-merge.md that make the two halves of the picture.
PICTURE_COMMANDS = (
    "splatconv bake dancers.splatv moment.ply --time 0.3",
    "splatconv render dancers.splatv 4d.png --time 0.3 --size 480x270 --fx 375 --fy 375",
    "splatconv render moment.ply baked.png --time 0.9 --size 480x270 --fx 375 --fy 375",
)


def run_line(line: str):
    result = CliRunner().invoke(main, shlex.split(line)[1:])
    assert result.exit_code == 0, (line, result.output)
    return result


def make_picture(workdir: Path) -> np.ndarray:
    """Run the picture's commands in ``workdir`` (which holds ``dancers.splatv``); the picture, RGB."""
    for line in PICTURE_COMMANDS:
        run_line(line)
    left = np.asarray(Image.open(workdir / "4d.png").convert("RGB"))
    right = np.asarray(Image.open(workdir / "baked.png").convert("RGB"))
    return side_by_side(left, right)


def _sample(workdir: Path) -> None:
    os.symlink(ROOT / "sample_data", workdir / "sample_data")
    run_line("splatconv convert sample_data/dancers.ply dancers.splatv --cameras sample_data/cameras.json")


def test_bake_picture_is_what_its_commands_draw(monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)
    _sample(tmp_path)
    made = make_picture(tmp_path)
    shown = np.asarray(Image.open(PICTURE).convert("RGB"))
    assert compare(made, shown).psnr >= 40
    # The two halves are the same moment: the baked scene drawn at another time matches the 4D scene.
    half = (made.shape[1] - 4) // 2
    assert compare(made[:, :half], made[:, half + 4:]).psnr >= 40


def test_bake_and_overlay_from_python(monkeypatch, tmp_path):
    """What the page's Python example says: a baked moment writes as a .splat, and overlay keeps every splat."""
    import splatconv
    from splatconv.ops.bake import bake
    from splatconv.ops.merge import overlay

    monkeypatch.chdir(tmp_path)
    _sample(tmp_path)
    moment, report = bake(splatconv.read("dancers.splatv"), 0.3)
    assert report.notes
    splatconv.write(moment, "moment.splat")
    both, _ = overlay([splatconv.read("dancers.splatv"), moment])
    assert both.count == 5_000 + moment.count
    assert (tmp_path / "moment.splat").stat().st_size == 32 * moment.count


def test_a_flipbook_is_numbered_frames(monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)
    _sample(tmp_path)
    run_line("splatconv bake dancers.splatv flipbook --frames 30")
    assert sorted(p.name for p in (tmp_path / "flipbook").iterdir())[::29] == ["frame_0000.ply", "frame_0029.ply"]


if __name__ == "__main__":
    with tempfile.TemporaryDirectory() as tmp:
        os.chdir(tmp)
        _sample(Path(tmp))
        Image.fromarray(make_picture(Path(tmp))).save(PICTURE)
    print(f"wrote {PICTURE}", file=sys.stderr)
