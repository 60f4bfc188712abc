"""Documentation that runs: every ``$ splatconv ...`` example in README.md and docs/*.md, and docs/cli.md.

Each page runs in a folder of its own that holds ``sample_data/`` and what the page's earlier
examples wrote, its examples in the order they appear. In a fenced block, a line that starts with
``$ splatconv`` is a command and the lines under it, up to the next ``$`` line, are what it prints
(its stderr lines, then its stdout lines); a command shown without output must exit 0 and may print
anything, one whose output ends in an ``Error: ...`` line must fail (exit 1, or 2 for usage), any
other must exit 0. A shown line ending in ``≈`` holds figures that depend on the GL driver (PSNR and pixel
errors of drawn frames): its words are compared, its numbers only as numbers. ````python`` blocks run
in the same folder, in order with the commands. A picture a page shows (``![...](NAME)``) whose
name an example wrote is compared with it by pixels (40 dB or better, every frame of an animation).
"""

from __future__ import annotations

import importlib.util
import os
import re
import shlex
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from splatconv.cli import commands, main

ROOT = Path(__file__).resolve().parent.parent
PAGES = [ROOT / "README.md"] + sorted((ROOT / "docs").glob("*.md"))
#: The end of a shown line whose numbers depend on the GL driver.
DRIVER = "≈"
_NUMBER = r"[-+]?(?:\d[\d,]*\.?\d*(?:e[-+]?\d+)?|inf|nan)"

FENCE = re.compile(r"^```(\w*)\n(.*?)^```", re.S | re.M)


def examples(text: str) -> list:
    """A page's runnable examples in order: ``("command", line, shown lines)`` or ``("python", code, None)``."""
    out = []
    for lang, body in FENCE.findall(text):
        if lang == "python":
            out.append(("python", body, None))
            continue
        if lang not in ("", "console"):
            continue
        current = None
        for line in body.splitlines():
            if line.startswith("$ "):
                current = ("command", line[2:], [])
                out.append(current)
            elif current is not None:
                current[2].append(line)
    return out


def _matches(shown: str, printed: str) -> bool:
    if not shown.endswith(DRIVER):
        return shown == printed
    # Word by word (a wider figure shifts the columns): numbers as numbers, every other word exact.
    words, got = shown[: -len(DRIVER)].split(), printed.split()
    return len(words) == len(got) and all(
        (re.fullmatch(_NUMBER + "%?", w) and re.fullmatch(_NUMBER + "%?", g)) or w == g for w, g in zip(words, got))


def _psnr(a: np.ndarray, b: np.ndarray) -> float:
    mse = ((a.astype(np.float64) - b.astype(np.float64)) ** 2).mean()
    return float("inf") if mse == 0 else 10 * np.log10(255.0**2 / mse)


def _frames(path: Path) -> list:
    from PIL import Image, ImageSequence

    return [np.asarray(f.convert("RGB")) for f in ImageSequence.Iterator(Image.open(path))]


def run_page(page: Path, folder: Path) -> list:
    """Run ``page``'s examples in ``folder`` (the current directory); the pictures checked, by name."""
    os.symlink(ROOT / "sample_data", folder / "sample_data")
    text = page.read_text(encoding="utf-8")
    for kind, code, shown in examples(text):
        if kind == "python":
            exec(compile(code, str(page), "exec"), {"__name__": "__doc_example__"})  # noqa: S102 (the page's own)
            continue
        words = shlex.split(code)
        assert words[0] == "splatconv", f"{page.name}: only splatconv commands run: {code}"
        result = CliRunner().invoke(main, words[1:], prog_name="splatconv")
        refused = bool(shown) and shown[-1].startswith("Error: ")
        assert result.exit_code in ((1, 2) if refused else (0,)), f"{page.name}: $ {code}\n{result.output}"
        if shown:
            printed = result.stderr.splitlines() + result.stdout.splitlines()
            assert len(printed) == len(shown) and all(map(_matches, shown, printed)), (
                f"{page.name}: $ {code}\nshown:\n" + "\n".join(shown) + "\nprinted:\n" + "\n".join(printed))
    checked = []
    for name in re.findall(r"!\[[^]]*\]\(([^)]+)\)", text):
        made = folder / Path(name).name
        if made.exists():
            ours, shown_frames = _frames(made), _frames(page.parent / name)
            assert len(ours) == len(shown_frames), name
            worst = min(_psnr(a, b) for a, b in zip(ours, shown_frames))
            assert worst >= 40, f"{page.name}: {name} is not what its example draws ({worst:.1f} dB)"
            checked.append(Path(name).name)
    return checked


@pytest.mark.parametrize("page", PAGES, ids=[p.name for p in PAGES])
def test_every_example_runs_and_prints_what_is_shown(page, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    checked = run_page(page, tmp_path)
    if page.name == "verify.md":
        # The preview pictures are these examples' output (by pixels: drivers may round differently).
        assert sorted(checked) == ["dancers.gif", "dancers_sheet.png"]


def test_the_harness_reads_commands_output_and_driver_lines():
    page = "text\n```\n$ splatconv info a.splatv\ncount: 1\n$ splatconv convert a b\n```\n```python\nx = 1\n```\n"
    assert examples(page) == [("command", "splatconv info a.splatv", ["count: 1"]),
                              ("command", "splatconv convert a b", []), ("python", "x = 1\n", None)]
    assert _matches(" 0.500       0     59.32        6     0.061      0.000%  ≈",
                    " 0.500       0     58.01       12     0.104      0.013%")
    assert not _matches("PASS: 3 frames at or above 40 dB  ≈", "FAIL: 3 frames at or above 40 dB")
    assert not _matches(" 0.500       0     59.32  ≈", " 0.500       0")
    assert not _matches("count: 1", "count: 2")


def test_every_page_runs_something():
    for page in PAGES:
        if page.name not in ("cli.md", "architecture.md", "development.md"):
            assert examples(page.read_text(encoding="utf-8")), f"{page.name} shows no example that runs"


# The Quick start: .ci/run runs its block's two lines, exactly as written, in a fresh virtual environment.

def quick_start_commands() -> list:
    section = (ROOT / "README.md").read_text(encoding="utf-8").split("## Quick start", 1)[1]
    return re.search(r"```\n(.*?)```", section, re.S).group(1).strip().splitlines()


def test_quick_start_has_two_commands_install_and_test():
    lines = quick_start_commands()
    assert len(lines) == 2
    assert lines[0].startswith("pip install . && mkdir -p out && splatconv convert sample_data/")
    assert lines[1] == "pip install '.[test]' && python -m pytest"
    # The output goes into out/ (ignored by git), not into the checkout's root.
    assert shlex.split(lines[0].split("&&")[-1])[3] == "out/dancers.splatv"
    assert "/out/" in (ROOT / ".gitignore").read_text().splitlines()


def test_quick_start_conversion_runs(tmp_path, monkeypatch):
    os.symlink(ROOT / "sample_data", tmp_path / "sample_data")
    monkeypatch.chdir(tmp_path)
    (tmp_path / "out").mkdir()
    words = shlex.split(quick_start_commands()[0].split("&&")[-1])
    result = CliRunner().invoke(main, words[1:])
    assert result.exit_code == 0, result.output
    assert (tmp_path / "out" / "dancers.splatv").stat().st_size > 0


def test_the_readme_lists_every_command_once():
    rows = re.findall(r"^\| `([a-z]+)` \|", (ROOT / "README.md").read_text(encoding="utf-8"), re.M)
    assert sorted(rows) == sorted(commands())


def test_the_readme_is_the_front_door():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    assert len(text.splitlines()) <= 200
    # Every page of docs/ is linked from it.
    for page in (ROOT / "docs").glob("*.md"):
        assert f"](docs/{page.name})" in text, page.name


# docs/cli.md: each command's --help, generated by docs/make_cli.py.

def _make_cli():
    spec = importlib.util.spec_from_file_location("make_cli", ROOT / "docs" / "make_cli.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_cli_reference_is_current():
    stored = (ROOT / "docs" / "cli.md").read_text(encoding="utf-8")
    assert stored == _make_cli().reference(), "docs/cli.md is out of date: run `python docs/make_cli.py`"


def test_the_cli_reference_holds_every_commands_help():
    text = _make_cli().reference()
    for name in commands():
        assert f"\n## splatconv {name}\n" in text
        assert f"Usage: splatconv {name} [OPTIONS]" in text
