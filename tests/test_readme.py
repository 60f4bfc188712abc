"""The README's commands and printed examples are true."""

from __future__ import annotations

import os
import re
import shlex
from pathlib import Path

from click.testing import CliRunner

from splatconv.cli import commands, main

ROOT = Path(__file__).resolve().parent.parent
README = (ROOT / "README.md").read_text()


def quick_start_commands() -> list:
    section = README.split("## Quick start", 1)[1]
    block = re.search(r"```\n(.*?)```", section, re.S).group(1)
    return block.strip().splitlines()


def splatconv_args(line: str) -> list:
    """The splatconv part of 'pip install ... && mkdir -p ... && splatconv ...'."""
    words = shlex.split(line.split("&&")[-1])
    assert words[0] == "splatconv"
    return words[1:]


def quick_start(monkeypatch, tmp_path) -> None:
    """Run the Quick start's conversion in ``tmp_path`` (a copy of the checkout, as CI runs it), then stand
    where the examples below it run: in the folder of its output, ``sample_data/`` beside it."""
    os.symlink(ROOT / "sample_data", tmp_path / "sample_data")
    monkeypatch.chdir(tmp_path)
    *setup, convert = quick_start_commands()[0].split("&&")
    for step in setup[1:]:  # after pip install
        assert shlex.split(step)[:2] == ["mkdir", "-p"]
        for folder in shlex.split(step)[2:]:
            os.makedirs(folder, exist_ok=True)
    args = splatconv_args(convert)
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 0, result.output
    out = os.path.dirname(args[2])
    assert out, "the Quick start writes its output into the checkout's root"
    monkeypatch.chdir(tmp_path / out)
    os.symlink(ROOT / "sample_data", tmp_path / out / "sample_data")


def test_quick_start_has_two_commands_install_and_test():
    lines = quick_start_commands()
    assert len(lines) == 2
    assert lines[0].startswith("pip install . && mkdir -p out && splatconv convert sample_data/")
    assert lines[1] == "pip install '.[test]' && python -m pytest"
    # The output goes into out/ (ignored by git), not into the checkout's root.
    assert splatconv_args(lines[0])[2] == "out/dancers.splatv"
    assert "/out/" in (ROOT / ".gitignore").read_text().splitlines()


def test_quick_start_conversion_and_info_example(monkeypatch, tmp_path):
    quick_start(monkeypatch, tmp_path)
    example = re.search(r"\$ splatconv info (\S+)\n(.*?)```", README, re.S)
    result = CliRunner().invoke(main, ["info", example.group(1)])
    assert result.exit_code == 0
    assert result.stdout == example.group(2)


def test_verify_example_runs_and_passes(monkeypatch, tmp_path):
    os.symlink(ROOT / "sample_data", tmp_path / "sample_data")
    monkeypatch.chdir(tmp_path)
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


def test_stats_example(monkeypatch, tmp_path):
    quick_start(monkeypatch, tmp_path)
    block = README.split("$ splatconv stats ", 1)[1]
    command, printed = block.split("\n", 1)
    printed = printed.split("```", 1)[0]
    result = CliRunner().invoke(main, ["stats"] + shlex.split(command))
    assert result.exit_code == 0, result.output
    assert result.stdout == printed


def section(title: str) -> str:
    """The README text from ``title`` to the next heading."""
    return re.split(r"\n#{2,3} ", README.split(title + "\n", 1)[1], maxsplit=1)[0]


def psnr(a, b) -> float:
    import numpy as np

    mse = ((np.asarray(a, np.float64) - np.asarray(b, np.float64)) ** 2).mean()
    return float("inf") if mse == 0 else 10 * np.log10(255.0**2 / mse)


def test_preview_commands_run_and_draw_the_pictures_shown(monkeypatch, tmp_path):
    from PIL import Image, ImageSequence

    quick_start(monkeypatch, tmp_path)
    text = section("### Previews without a browser")
    lines = re.search(r"```\n(.*?)```", text, re.S).group(1).strip().splitlines()
    assert len(lines) == 3 and all(ln.startswith("splatconv render dancers.splatv ") for ln in lines)
    for line in lines:
        result = CliRunner().invoke(main, shlex.split(line)[1:])
        assert result.exit_code == 0, (line, result.output)
    assert Image.open("frame.png").size == (1280, 720)
    # The README's pictures are these commands' output (by pixels: drivers may round differently).
    pictures = dict(re.findall(r"!\[([^]]*)\]\((docs/[^)]+)\)", text))
    sheet = Image.open(ROOT / pictures["The sample scene at four times"])
    assert psnr(Image.open("sheet.png").convert("RGB"), sheet.convert("RGB")) >= 40
    ours = [f.convert("RGB") for f in ImageSequence.Iterator(Image.open("sweep.gif"))]
    shown = [f.convert("RGB") for f in ImageSequence.Iterator(Image.open(ROOT / pictures["The sample scene animated"]))]
    assert len(ours) == len(shown) == 24
    assert min(psnr(a, b) for a, b in zip(ours, shown)) >= 40


def test_image_diff_example(monkeypatch, tmp_path):
    import numpy as np
    from PIL import Image

    monkeypatch.chdir(tmp_path)
    a = np.zeros((20, 30, 3), np.uint8)
    b = a.copy()
    b[5, 5] = [30, 0, 0]
    Image.fromarray(a).save("a.png")
    Image.fromarray(b).save("b.png")
    text = section("### Proving a conversion: verify and diff")
    example = re.search(r"```\n(A +B +PSNR dB.*?)```", text, re.S).group(1)
    result = CliRunner().invoke(main, ["diff", "a.png", "b.png"])
    assert result.exit_code == 0
    assert result.stdout == example


def test_commands_summary_names_every_command_and_only_real_options():
    """The README's command summary lists each command, and every option it shows exists."""
    block = re.search(r"## Commands\n\n```\n(.*?)```", README, re.S).group(1)
    seen = set()
    command = None
    for line in block.splitlines():
        words = line.split()
        if words and words[0] == "splatconv":
            command = next((w for w in words[1:] if not w.startswith("-") and w in commands()), None)
            seen.add(command)
        options = set(re.findall(r"(?<![\w-])(--?[a-z][a-z-]*)", line))
        params = commands()[command].params + main.params if command else main.params
        known = {o for p in params for o in p.opts + p.secondary_opts}
        assert options <= known, f"{line.strip()}: not options of {command}: {sorted(options - known)}"
    assert seen - {None} == set(commands()), sorted(set(commands()) - seen)
