"""The command line: exact error lines and exit codes, safe output, determinism."""

from __future__ import annotations

import errno
import json
import sys
import os
import struct

import numpy as np
import pytest
from click.testing import CliRunner

from splatconv.cli import commands, main
from splatconv.formats import ply

from .conftest import lite_columns_with_normals, random_columns, write_ply

N = 20
_ARR = np.zeros(N, ply.LITE_DTYPE)
_HDR = ply.header_bytes(N, None)
GOOD_PLY = _HDR + _ARR.tobytes()
OK_CHUNK = {"type": "splat", "size": 4096 * 16, "texwidth": 4096, "texheight": 1, "cameras": []}


def _sv(chunks, body=b"") -> bytes:
    text = json.dumps(chunks).encode()
    return struct.pack("<II", 0x674B, len(text)) + text + body


def _raw(text: bytes, declared=None) -> bytes:
    return struct.pack("<II", 0x674B, len(text) if declared is None else declared) + text


# (file name, bytes, the exact error after "Error: <name>: ")
INVALID_CASES = [
    ("empty.ply", b"", "file is empty"),
    ("notply.ply", b"hello world\n", "line 1: bad header: expected 'ply'"),
    ("noend.ply", b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n",
     "line 5: bad header: early end-of-file"),
    ("badformat.ply", b"ply\nformat binary_middle_endian 1.0\nelement vertex 1\nproperty float x\nend_header\n",
     "line 2: bad header: don't understand format 'binary_middle_endian'"),
    ("truncated.ply", GOOD_PLY[:len(_HDR) + 1285],
     "element 'vertex': header declares 20 rows (2560 bytes) but only 1285 bytes follow the header: "
     "file truncated?"),
    ("huge.ply", _HDR.replace(b"vertex 20", b"vertex 1000000000000") + _ARR.tobytes(),
     "element 'vertex': header declares 1000000000000 rows (128000000000000 bytes) but only 2560 bytes "
     "follow the header: file truncated?"),
    ("hugeascii.ply", b"ply\nformat ascii 1.0\nelement vertex 1000000000000\nproperty float x\nend_header\n1\n",
     "element 'vertex': header declares 1000000000000 rows (at least 1999999999999 bytes) but only 2 bytes "
     "follow the header: file truncated?"),
    ("badascii.ply", b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
                     b"end_header\n1 2\n3 abc\n", "element 'vertex': row 1: property 'y': malformed input"),
    ("noverts.ply", b"ply\nformat ascii 1.0\nelement face 1\nproperty float x\nend_header\n1\n",
     "not a splat file: no 'vertex' element (elements: face)"),
    ("mesh.ply", b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
                 b"property float z\nend_header\n1 2 3\n",
     "not a splat file: missing properties f_dc_0, f_dc_1, f_dc_2, opacity, scale_0, scale_1, scale_2, "
     "rot_0, rot_1, rot_2, rot_3 (needed for plain 3DGS)"),
    ("camjson.ply", _HDR.replace(b"element vertex", b"comment splatconv-cameras [{\nelement vertex", 1) + _ARR.tobytes(),
     "cameras comment: Expecting property name enclosed in double quotes (line 1, column 3)"),
    ("camnan.ply", _HDR.replace(b"element vertex", b"comment splatconv-cameras [NaN]\nelement vertex", 1)
     + _ARR.tobytes(), "cameras comment: NaN is not allowed in strict JSON"),
    ("camkeys.ply", _HDR.replace(b"element vertex", b"comment splatconv-cameras [{}]\nelement vertex", 1)
     + _ARR.tobytes(), "cameras comment: camera 0: missing id, img_name, width, height, position, rotation, "
     "fy, fx"),
    ("zero.ply", _HDR.replace(b"vertex 20", b"vertex 0"),
     "holds no splats; a .splatv file cannot hold an empty scene"),
    ("short.splatv", b"\x4b\x67", "2 bytes is too short for a .splatv file (8-byte preamble)"),
    ("magic.splatv", struct.pack("<II", 0x1234, 2) + b"[]", "not a .splatv file: magic 0x00001234, expected 0x0000674b"),
    ("jsonlen.splatv", _raw(b"[]", 1000), "header declares 1000 bytes of JSON but the file ends after 2"),
    ("jsonhuge.splatv", _raw(b"[]", 2**31),
     "header declares 2147483648 bytes of JSON, more than the 67108864 allowed"),
    ("badjson.splatv", _raw(b"[{"),
     "header JSON: Expecting property name enclosed in double quotes (line 1, column 3)"),
    ("nanjson.splatv", _raw(b'[{"type":"splat","size":NaN}]'), "header JSON: NaN is not allowed in strict JSON"),
    ("utf8.splatv", _raw(b"\xff\xfe["), "header JSON: not UTF-8 (byte 0)"),
    ("notarray.splatv", _sv({"type": "splat"}), "header JSON must be an array of chunks"),
    ("nosize.splatv", _sv([{"type": "splat"}]), "chunk 0: 'size' must be a non-negative integer, got None"),
    ("nosplat.splatv", _sv([{"type": "audio", "size": 0}]), "header has no 'splat' chunk"),
    ("texwidth.splatv", _sv([dict(OK_CHUNK, texwidth=2048)]),
     "chunk 0: 'texwidth' is 2048; the viewer's shader needs 4096"),
    ("sizemismatch.splatv", _sv([dict(OK_CHUNK, size=100)]),
     "chunk 0: 'size' is 100 but texwidth*texheight*16 is 65536"),
    ("hugetex.splatv", _sv([dict(OK_CHUNK, texheight=15258789062, size=4096 * 15258789062 * 16)]),
     "chunk 0: 'texheight' 15258789062 is past the largest texture any GPU takes (65536)"),
    ("hugechunk.splatv", _sv([{"type": "audio", "size": 10**15}, OK_CHUNK]),
     "chunk 0 ('audio'): declares 1000000000000000 bytes but the file ends 0 bytes after its start, "
     "before any splat chunk"),
    ("badcam.splatv", _sv([dict(OK_CHUNK, cameras=[{"id": 0}])]),
     "chunk 0: cameras: camera 0: missing img_name, width, height, position, rotation, fy, fx"),
    ("empty.splatv", _sv([OK_CHUNK], bytes(4096 * 16)),
     "holds no splats; a .splatv file cannot hold an empty scene"),
]


@pytest.mark.parametrize("name,data,message", INVALID_CASES, ids=[c[0] for c in INVALID_CASES])
def test_invalid_input_gives_one_error_line(monkeypatch, tmp_path, name, data, message):
    src = tmp_path / name
    src.write_bytes(data)
    out = tmp_path / ("out.ply" if name.endswith(".splatv") else "out.splatv")
    if name == "empty.splatv":
        out = tmp_path / "out.splatv"
    monkeypatch.chdir(tmp_path)
    result = CliRunner().invoke(main, ["convert", name, out.name])
    assert result.exit_code == 1, result.output
    assert result.stderr == f"Error: {name}: {message}\n"
    assert sorted(os.listdir(tmp_path)) == [name]  # nothing written, no temp file left
    assert src.read_bytes() == data


def run(*args, **kw):
    return CliRunner().invoke(main, [str(a) for a in args], **kw)


def test_convert_and_info_roundtrip(tmp_path, lite_ply):
    out = tmp_path / "s.splatv"
    r = run("convert", lite_ply, out)
    assert r.exit_code == 0, r.output
    assert r.stdout.startswith(f"wrote {out}: 3,000 splats")
    assert "note: no cameras given; wrote one camera that frames the scene" in r.stderr
    r = run("info", out, "--json")
    info = json.loads(r.stdout)
    assert info["count"] == 3000 and info["format"] == "splatv"
    assert info["texture"] == {"width": 4096, "height": 3, "declared_bytes": 4096 * 3 * 16,
                               "actual_bytes": 4096 * 3 * 16}
    assert len(info["cameras"]) == 1
    r = run("info", lite_ply)
    assert r.exit_code == 0
    assert "variant:   Spacetime Gaussians lite" in r.stdout


def test_info_lists_ignored_and_nonfinite(tmp_path):
    cols = lite_columns_with_normals(random_columns(10))
    cols["x"][3] = np.nan
    cols["trbf_scale"][4] = np.inf  # visible at every time: has a meaning
    cols["trbf_scale"][5] = -np.inf  # visible at no time: none
    p = write_ply(tmp_path / "e.ply", cols, extra_props=("f_rest_0",))
    info = json.loads(run("info", p, "--json").stdout)
    assert info["nonfinite"]["x"] == 1 and info["nonfinite"]["trbf_scale"] == 1
    assert info["visible_always"] == 1
    assert info["details"]["ignored_properties"] == ["f_rest_0"]
    assert info["variant"] == "Spacetime Gaussians lite"


def test_refuses_existing_output_without_force(tmp_path, lite_ply):
    out = tmp_path / "o.splatv"
    out.write_bytes(b"keep me")
    r = run("convert", lite_ply, out)
    assert r.exit_code == 1
    assert r.stderr == f"Error: {out}: already exists (use --force to replace it)\n"
    assert out.read_bytes() == b"keep me"
    assert run("convert", lite_ply, out, "--force").exit_code == 0
    assert out.read_bytes()[:4] == b"\x4b\x67\x00\x00"


@pytest.mark.parametrize("how", ["same", "symlink", "hardlink"])
def test_never_writes_onto_the_input(tmp_path, lite_ply, how):
    before = lite_ply.read_bytes()
    target = tmp_path / "alias.ply"
    if how == "same":
        target = lite_ply
    elif how == "symlink":
        target.symlink_to(lite_ply)
    else:
        os.link(lite_ply, target)
    r = run("convert", lite_ply, target, "--force")
    assert r.exit_code == 1
    assert r.stderr == f"Error: {target}: is the input file; refusing to write onto it\n"
    assert lite_ply.read_bytes() == before


def test_usage_errors_exit_2(tmp_path, lite_ply):
    r = run("convert", lite_ply, tmp_path / "x.obj")
    assert r.exit_code == 2
    assert r.stderr == f"Error: {tmp_path / 'x.obj'}: unknown file type (expected one of .compressed.ply, .glb, .gltf, .html, .ply, .sog, .splat, .splatv, .splatvq, .spz, optionally + .zst)\n"
    r = run("convert", lite_ply, tmp_path / "x.ply", "--compat", "splatv-js")
    assert r.exit_code == 2
    assert r.stderr == f"Error: {tmp_path / 'x.ply'}: --compat splatv-js applies to .splatv, .html output only\n"
    assert run("convert", lite_ply).exit_code == 2
    assert run("convert", lite_ply, tmp_path / "x.splatv", "--sort", "size").exit_code == 2
    assert not (tmp_path / "x.ply").exists()


@pytest.mark.parametrize("args, message", [
    (["convert", "a.ply"], "Missing argument 'INPUT...'. See 'main convert --help'."),
    (["convert", "a.ply", "b.splatv", "--sort", "size"],
     "Invalid value for '--sort': 'size' is not one of 'importance', 'none'. See 'main convert --help'."),
    (["frobnicate"], "No such command 'frobnicate'. See 'main --help'."),
    (["--max-decompressed", "3X", "info", "a.splatv"],
     "Invalid value for '--max-decompressed': expected a byte count such as 4G, 512M or 1000000, got '3X'. "
     "See 'main --help'."),
    (["bake", "a.splatv", "out", "--frames", "1"], "Invalid value for '--frames': 1 is not in the range 2<=x<=100000. "
                                                    "See 'main bake --help'."),
])
def test_click_usage_errors_are_one_error_line_too(tmp_path, monkeypatch, args, message):
    monkeypatch.chdir(tmp_path)
    r = run(*args)
    assert (r.exit_code, r.stdout, r.stderr) == (2, "", f"Error: {message}\n")


def test_missing_input(tmp_path):
    r = run("convert", tmp_path / "nope.ply", tmp_path / "o.splatv")
    assert r.exit_code == 1
    assert r.stderr == f"Error: {tmp_path / 'nope.ply'}: cannot open: No such file or directory\n"


def test_cameras_option_and_roundtrip(tmp_path, lite_ply):
    cams = [{"id": 0, "img_name": "cam00", "width": 640, "height": 480, "position": [0, 0, -5],
             "rotation": [[1, 0, 0], [0, 1, 0], [0, 0, 1]], "fy": 500.0, "fx": 510.0},
            {"id": 1, "img_name": "cam01", "width": 640, "height": 480, "position": [1, 0, -5],
             "rotation": [[1, 0, 0], [0, 1, 0], [0, 0, 1]], "fy": 500.0, "fx": 510.0}]
    cfile = tmp_path / "cameras.json"
    cfile.write_text(json.dumps(cams))
    out = tmp_path / "c.splatv"
    assert run("convert", lite_ply, out, "--cameras", cfile).exit_code == 0
    data = out.read_bytes()
    n = struct.unpack("<I", data[4:8])[0]
    assert json.loads(data[8:8 + n])[0]["cameras"] == cams
    assert run("convert", out, tmp_path / "c.ply").exit_code == 0
    assert run("convert", tmp_path / "c.ply", tmp_path / "d.splatv", "--sort", "none").exit_code == 0
    assert json.loads(run("info", tmp_path / "d.splatv", "--json").stdout)["cameras"][1]["img_name"] == "cam01"
    assert (tmp_path / "d.splatv").read_bytes() == data


@pytest.mark.parametrize("content,message", [
    ("[]", "holds no cameras; the viewer needs at least one"),
    ("{", "invalid JSON: Expecting property name enclosed in double quotes (line 1, column 2)"),
    ('[{"id": 0}]', "camera 0: missing img_name, width, height, position, rotation, fy, fx"),
    ("[NaN]", "invalid JSON: NaN is not allowed in strict JSON"),
])
def test_bad_cameras_file(tmp_path, lite_ply, content, message):
    cfile = tmp_path / "cams.json"
    cfile.write_text(content)
    r = run("convert", lite_ply, tmp_path / "o.splatv", "--cameras", cfile)
    assert r.exit_code == 1
    assert r.stderr == f"Error: {cfile}: {message}\n"
    assert not (tmp_path / "o.splatv").exists()


@pytest.mark.parametrize("args", [[], ["--compat", "splatv-js"], ["--sort", "none"]])
def test_two_runs_give_identical_bytes(tmp_path, lite_ply, args):
    a, b = tmp_path / "a.splatv", tmp_path / "b.splatv"
    assert run("convert", lite_ply, a, *args).exit_code == 0
    assert run("convert", lite_ply, b, *args).exit_code == 0
    assert a.read_bytes() == b.read_bytes()
    assert run("convert", a, tmp_path / "a.ply").exit_code == 0
    assert run("convert", a, tmp_path / "b.ply").exit_code == 0
    assert (tmp_path / "a.ply").read_bytes() == (tmp_path / "b.ply").read_bytes()


def test_lossy_steps_are_reported(tmp_path):
    cols = lite_columns_with_normals(random_columns(10))
    cols["scale_0"][0] = 20.0  # exp(20) is past the half range
    cols["f_dc_1"][1] = 1.5
    p = write_ply(tmp_path / "l.ply", cols)
    r = run("convert", p, tmp_path / "l.splatv")
    assert "note: scale_0: 1 value past the half-float range saturated to +-65504" in r.stderr
    assert "note: color: 1 value outside [0, 1] clamped" in r.stderr
    r = run("convert", p, tmp_path / "j.splatv", "--compat", "splatv-js")
    assert "note: scale_0: 1 value past the half-float range became infinity (splaTV's converter)" in r.stderr


def test_help_for_every_command():
    assert set(commands()) >= {"convert", "info", "render", "verify", "diff", "stats"}
    r = run("--help")
    assert r.exit_code == 0 and r.stdout.startswith("Usage: main [OPTIONS] COMMAND")
    listing = r.stdout
    for name, command in commands().items():
        r = run(name, "--help")
        assert r.exit_code == 0, (name, r.output)
        assert r.stdout.startswith(f"Usage: main {name} ")
        assert command.help and command.help.strip(), name
        first_paragraph = " ".join(command.help.strip().split("\n\n")[0].split())
        assert first_paragraph and first_paragraph in " ".join(r.stdout.split()), name
        assert f"\n  {name} " in listing  # listed in the group's help


def test_help_documents_each_commands_defaults():
    diff_help = " ".join(run("diff", "--help").stdout.split())
    assert "[default: 0.5]" in diff_help and "[default: 0]" in diff_help
    assert "drawn at one time from one camera" in diff_help
    verify_help = " ".join(run("verify", "--help").stdout.split())
    assert "[default: 0,0.25,0.5,0.75,1]" in verify_help and "[default: the first 8]" in verify_help
    for cmd in ("verify", "diff"):
        assert "fx and fy scale with the size" in " ".join(run(cmd, "--help").stdout.split()), cmd
    assert "An explicit size keeps the camera's fx and fy" in " ".join(run("render", "--help").stdout.split())


class _FailingWrites:
    """A binary file that fails like a full disk or a file size limit after ``budget`` bytes."""

    def __init__(self, f, budget: int, code: int, message: str):
        self._f, self._left, self._error = f, budget, OSError(code, message)

    def write(self, data) -> int:
        view = memoryview(data).cast("B")
        if len(view) > self._left:
            self._f.write(view[:self._left])
            self._left = 0
            raise self._error  # as write(2) reports it: no file name
        self._left -= len(view)
        return self._f.write(view)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return self._f.__exit__(*exc)

    def __getattr__(self, name):
        return getattr(self._f, name)


def fail_writes_after(monkeypatch, budget: int, code: int, message: str) -> None:
    """Make files opened by the atomic writer fail with ``OSError(code)`` after ``budget`` bytes."""
    from splatconv.files import output as atomic_output

    real = os.fdopen
    monkeypatch.setattr(atomic_output.os, "fdopen", lambda fd, *a, **kw: _FailingWrites(real(fd, *a, **kw), budget,
                                                                                  code, message))


@pytest.mark.parametrize("code,message", [(errno.EFBIG, "File too large"), (errno.ENOSPC, "No space left on device")])
@pytest.mark.parametrize("output", ["x.splatv", "x.ply", "x.splatv.zst"])
def test_os_error_while_writing_names_the_output_and_leaves_nothing(tmp_path, lite_ply, monkeypatch, code,
                                                                    message, output):
    monkeypatch.chdir(tmp_path)
    before = sorted(tmp_path.iterdir())
    fail_writes_after(monkeypatch, 1000, code, message)
    r = run("convert", lite_ply, output)
    assert r.exit_code == 1 and r.stdout == ""
    assert r.stderr == f"Error: {output}: {message}\n"
    assert sorted(tmp_path.iterdir()) == before  # no partial output, no temporary file


def test_os_error_replacing_an_output_keeps_the_old_one(tmp_path, lite_ply, monkeypatch):
    out = tmp_path / "x.splatv"
    out.write_bytes(b"old")
    fail_writes_after(monkeypatch, 10, errno.ENOSPC, "No space left on device")
    r = run("convert", lite_ply, out, "--force")
    assert r.exit_code == 1 and r.stderr == f"Error: {out}: No space left on device\n"
    assert out.read_bytes() == b"old" and sorted(p.name for p in tmp_path.iterdir()) == sorted(
        [lite_ply.name, "x.splatv"])


def test_conversion_does_not_import_moderngl(tmp_path, lite_ply):
    import subprocess
    import sys
    code = ("import sys, splatconv; splatconv.convert(sys.argv[1], sys.argv[2]); "
            "assert 'moderngl' not in sys.modules")
    subprocess.run([sys.executable, "-c", code, str(lite_ply), str(tmp_path / "m.splatv")], check=True)


def test_every_command_help_shows_an_example():
    for name in commands():
        text = run(name, "--help").stdout
        assert "Example:" in text and "  splatconv " in text, name


def test_shared_options_are_listed_in_declaration_order():
    text = run("verify", "--help").stdout
    at = [text.index(f"\n  {opt} ") for opt in ("--times", "--cameras", "--size", "--min-psnr", "--json", "--color")]
    assert at == sorted(at)


def test_python_dash_m_runs_the_command(sample_splatv):
    import subprocess

    from pathlib import Path

    r = subprocess.run([sys.executable, "-m", "splatconv", "info", str(sample_splatv)], capture_output=True,
                       text=True, cwd=Path(__file__).resolve().parent.parent)
    assert r.returncode == 0, r.stderr
    assert "count:     5,000 splats" in r.stdout


def test_info_takes_several_files(tmp_path, sample_splatv, lite_ply):
    r = run("info", sample_splatv, lite_ply)
    assert r.exit_code == 0, r.output
    assert r.stdout.count("file:      ") == 2
    data = json.loads(run("info", "--json", sample_splatv, lite_ply).stdout)
    assert [d["format"] for d in data] == ["splatv", "ply"]
    common = {"path", "format", "variant", "count", "texture", "cameras", "time_range", "visible_time_range",
              "visible_always", "bounds", "nonfinite", "notes"}
    assert common <= set(data[0]) and common <= set(data[1])


def _stderr_on_a_terminal(args, cwd):
    """Run ``python -m splatconv ARGS`` with stderr on a pseudo-terminal; what it wrote there."""
    import pty
    import subprocess

    master, slave = pty.openpty()
    proc = subprocess.run([sys.executable, "-m", "splatconv", *args], stderr=slave, stdout=subprocess.PIPE,
                          cwd=cwd)
    os.close(slave)
    out = b""
    while True:
        try:
            chunk = os.read(master, 65536)
        except OSError:
            break
        if not chunk:
            break
        out += chunk
    os.close(master)
    assert proc.returncode == 0, out
    return out.decode()


def test_progress_shows_on_a_terminal_and_not_with_quiet_or_in_a_pipe(tmp_path, lite_ply):
    from pathlib import Path

    root = Path(__file__).resolve().parent.parent
    shown = _stderr_on_a_terminal(["convert", str(lite_ply), str(tmp_path / "a.splatv")], root)
    assert "writing:" in shown and "splats" in shown
    assert shown.count("\r\x1b[K") >= 1  # the bar is cleared when its stage ends
    quiet = _stderr_on_a_terminal(["convert", "--quiet", str(lite_ply), str(tmp_path / "b.splatv")], root)
    assert "writing:" not in quiet
    piped = run("convert", lite_ply, tmp_path / "c.splatv")
    assert piped.exit_code == 0 and "writing:" not in piped.stderr
    # Compressing a .zst output and decompressing a .zst input show too.
    packed = str(tmp_path / "d.splatv.zst")
    assert "compressing:" in _stderr_on_a_terminal(["convert", str(lite_ply), packed], root)
    shown = _stderr_on_a_terminal(["convert", packed, str(tmp_path / "e.ply")], root)
    assert "reading:" in shown and "decompressing d.splatv.zst:" in shown


def test_a_stage_inside_another_gives_the_line_back_when_it_ends():
    import io

    from splatconv.cli._progress import progress_for

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    screen = Terminal()
    bar = progress_for(False, screen)
    with bar.stage("reading", 1, "file") as advance:
        with bar.stage("decompressing a.zst", 10, "byte") as inner:
            inner(10)
        assert screen.getvalue().rsplit("\r", 1)[-1].startswith("reading:")  # the outer bar is back
        advance()
    assert screen.getvalue().endswith("\r\x1b[K")  # cleared when the last stage ends
    assert progress_for(True, screen) is progress_for(False, io.StringIO())  # --quiet, or no terminal: silent


#: Colours a hair outside [0, 1] whose byte is 0 or 255 anyway, then ones the clamp changes:
#: (value, clamped rounding to nearest, clamped truncating as splaTV's converter does).
EDGE_COLOURS = [(-1.5e-8, False, False), (1.0 + 2**-23, False, False), (-0.4 / 255, False, False),
                (255.4 / 255, False, False), (-0.6 / 255, True, False), (255.6 / 255, True, False),
                (-1.0 / 255, True, True), (256.0 / 255, True, True), (-0.2, True, True), (1.5, True, True)]


@pytest.mark.parametrize("suffix, args, column", [(".splatv", [], 1), (".splatv", ["--compat", "splatv-js"], 2),
                                                  (".splat", [], 1), (".html", [], 1)])
def test_only_colours_whose_byte_the_clamp_changes_are_noted(tmp_path, suffix, args, column):
    cols = lite_columns_with_normals(random_columns(len(EDGE_COLOURS), 4))
    cols["f_dc_0"][:] = np.array([e[0] for e in EDGE_COLOURS], np.float32)
    cols["f_dc_1"][:] = 0.5
    cols["f_dc_2"][:] = 0.5
    for name in [f"motion_{i}" for i in range(9)] + [f"omega_{i}" for i in range(4)]:
        cols[name][:] = 0.0  # static, so that a .splat holds it
    cols["trbf_scale"][:] = np.inf
    clamped = sum(e[column] for e in EDGE_COLOURS)
    p = write_ply(tmp_path / "edge.ply", cols)
    r = run("convert", p, tmp_path / f"edge{suffix}", *args)
    assert r.exit_code == 0, r.output
    assert f"note: color: {clamped} values outside [0, 1] clamped\n" in r.stderr
    if suffix == ".splatv" and not args:
        stats = json.loads(run("stats", p, tmp_path / "edge.splatv", "--json", "--zstd-level", "1").stdout)
        assert stats["attributes"]["color"]["clamped"] == clamped


def test_a_baked_frame_converts_back_without_clamp_notes(tmp_path):
    # A baked 3DGS PLY stores colour as SH coefficients; read back, colours may sit a float32
    # hair outside [0, 1]: their bytes are 0 and 255 anyway, so converting changes nothing there.
    from .real_scenes import real_scene, unpadded_splatv

    scene, _ = real_scene(3000, 2)
    src = tmp_path / "scene.splatv"
    unpadded_splatv(scene, src)
    baked = tmp_path / "baked.ply"
    assert run("bake", src, baked, "--time", "0.5").exit_code == 0
    # The case in point, planted: colours a hair outside [0, 1] whose bytes are 0 and 255.
    cols = random_columns(50, seed=3)
    cols["f_dc_0"][:25] = np.float32(-1.5e-8)
    cols["f_dc_1"][25:] = np.nextafter(np.float32(1), np.float32(2))
    cols["rot_0"][:] = 1.0
    for name in [f"motion_{i}" for i in range(9)] + [f"omega_{i}" for i in range(4)]:
        cols[name][:] = 0.0
    cols["trbf_scale"][:] = np.inf  # static: a .splat may hold it
    hair = write_ply(tmp_path / "hair.ply", cols)
    for source in (baked, hair):
        for suffix in (".splatv", ".splat"):
            r = run("convert", source, tmp_path / f"back{suffix}", "--force")
            assert r.exit_code == 0 and "clamped" not in r.stderr, r.stderr


def test_a_file_ending_after_its_last_record_is_said_once_in_info(tmp_path):
    # Every real .splatv stops after its last record: nothing is lost, so only info says it.
    from .real_scenes import real_scene, unpadded_splatv

    scene, _ = real_scene(600, 1)
    p = tmp_path / "real.splatv"
    unpadded_splatv(scene, p)
    info = run("info", p)
    assert info.exit_code == 0
    assert info.stdout.count("pad") == 1 and "pad" not in info.stderr
    assert "texture:   4096 x 1 RGBA32UI, 65,536 bytes declared, 38,400 present (not padded: the rest reads " \
           "as zeros)\n" in info.stdout
    for args in (("convert", p, tmp_path / "out.ply"), ("stats", p, "--zstd-level", "1"),
                 ("render", p, tmp_path / "f.png", "--size", "32x18"),
                 ("verify", p, tmp_path / "out.ply", "--times", "0.5", "--cameras", "0", "--size", "32x18")):
        r = run(*args)
        notes = [line for line in r.output.splitlines() if line.startswith("note:")]
        assert r.exit_code in (0, 1) and not [n for n in notes if "pad" in n or "shorter" in n], (args, r.output)
    # Padded by its writer: info says nothing of padding.
    padded = tmp_path / "padded.splatv"
    assert run("convert", tmp_path / "out.ply", padded).exit_code == 0
    assert "not padded" not in run("info", padded).stdout
