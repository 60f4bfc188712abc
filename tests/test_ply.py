"""PLY reading: encodings, variants, extras; and the lite layout written back."""

from __future__ import annotations

import numpy as np
import plyfile
import pytest

import splatconv
from splatconv import model
from splatconv.errors import UnsupportedError
from splatconv.formats import ply

from .conftest import lite_columns_with_normals, random_columns, write_ply


@pytest.mark.parametrize("kw", [
    dict(), dict(byte_order=">"), dict(text=True), dict(dtype="f8"),
    dict(order=list(reversed(ply.LITE_LAYOUT))),
    dict(extra_props=("f_rest_0", "custom")), dict(comments=["made by a test"], obj_info=["obj"]),
    dict(extra_elements=[plyfile.PlyElement.describe(np.zeros(3, [("a", "i4")]), "face")]),
])
def test_lite_variants_read_identically(tmp_path, kw):
    cols = random_columns(200, 4)
    path = write_ply(tmp_path / "v.ply", lite_columns_with_normals(cols), **kw)
    scene = splatconv.read(path)
    assert scene.variant == model.VARIANT_LITE and scene.count == 200
    for name in model.COLUMNS:
        got = scene.columns[name]
        assert got.dtype == np.float32
        if kw.get("text"):
            assert np.allclose(got, cols[name], rtol=1e-6, atol=1e-7)
        else:
            assert np.array_equal(got, cols[name]), name
    if kw.get("dtype") == "f8":
        assert any("double properties narrowed" in n for n in scene.notes)
    if kw.get("extra_props"):
        assert scene.meta["ignored_properties"] == ["f_rest_0", "custom"]
    if kw.get("extra_elements"):
        assert scene.meta["extra_elements"] == ["face"]


def test_crlf_header(tmp_path):
    cols = lite_columns_with_normals(random_columns(5))
    arr = np.zeros(5, ply.LITE_DTYPE)
    for name in ply.LITE_LAYOUT:
        arr[name] = cols[name]
    header = ply.header_bytes(5, None).replace(b"\n", b"\r\n").replace(b"end_header\r\n",
                                                                       b"comment x\r\nend_header\r\n")
    header = header.replace(b"comment x\r\n", b"")
    p = tmp_path / "crlf.ply"
    p.write_bytes(header + arr.tobytes())
    assert np.array_equal(splatconv.read(p).columns["opacity"], cols["opacity"])


def test_plain_3dgs_becomes_static_scene_with_sh_colour(gs_ply):
    scene = splatconv.read(gs_ply)
    assert scene.variant == model.VARIANT_3DGS
    raw = plyfile.PlyData.read(str(gs_ply))["vertex"]
    assert np.allclose(scene.columns["f_dc_1"], 0.5 + ply.SH_C0 * raw["f_dc_1"], rtol=1e-6, atol=1e-7)
    assert not np.any(scene.columns["motion_4"]) and not np.any(scene.columns["omega_2"])
    # visible at every time in [0, 1]: exp(-(dt/s)^2) stays ~1
    dt = np.array([0.0, 1.0]) - scene.columns["trbf_center"][0]
    assert np.all(np.exp(-(dt / np.exp(float(scene.columns["trbf_scale"][0]))) ** 2) > 0.999)
    # its SH bands (degree 3: 45 f_rest_*) are kept as they are, nothing dropped
    assert scene.sh_degree == 3 and np.array_equal(scene.columns["f_rest_44"], raw["f_rest_44"])
    assert not any("f_rest_" in n for n in scene.notes)
    assert splatconv.read(gs_ply, color="rgb").columns["f_dc_0"][3] == raw["f_dc_0"][3]


def test_lite_can_be_read_as_sh(lite_ply):
    a = splatconv.read(lite_ply).columns["f_dc_2"]
    b = splatconv.read(lite_ply, color="sh").columns["f_dc_2"]
    assert np.allclose(b, 0.5 + ply.SH_C0 * a, rtol=1e-6, atol=1e-7)


def test_full_model_is_refused_with_explanation(tmp_path):
    cols = lite_columns_with_normals(random_columns(4))
    cols.update({f"f_dc_{i}": np.zeros(4, np.float32) for i in range(3, 6)})
    cols.update({f"f_t_{i}": np.zeros(4, np.float32) for i in range(3)})
    with pytest.raises(UnsupportedError, match="full model .* lite model, which stores RGB"):
        splatconv.read(write_ply(tmp_path / "full.ply", cols))


@pytest.mark.parametrize("drop,expect", [
    (("omega_0", "omega_3"), "missing properties omega_0, omega_3 (needed for Spacetime Gaussians lite)"),
])
def test_missing_properties_are_named(tmp_path, drop, expect):
    cols = {k: v for k, v in lite_columns_with_normals(random_columns(4)).items() if k not in drop}
    with pytest.raises(UnsupportedError) as e:
        splatconv.read(write_ply(tmp_path / "m.ply", cols))
    assert expect in str(e.value)


def test_mesh_is_not_a_splat_file(tmp_path):
    cols = {k: np.zeros(3, np.float32) for k in ("x", "y", "z", "red")}
    with pytest.raises(UnsupportedError) as e:
        splatconv.read(write_ply(tmp_path / "mesh.ply", cols))
    assert "not a splat file: missing properties f_dc_0, f_dc_1, f_dc_2, opacity, scale_0" in str(e.value)


def test_lite_layout_written_in_exact_order(tmp_path, lite_ply):
    out = tmp_path / "out.ply"
    splatconv.convert(lite_ply, out)
    data = plyfile.PlyData.read(str(out))
    assert [p.name for p in data["vertex"].properties] == list(ply.LITE_LAYOUT)
    assert all(p.val_dtype == "f4" for p in data["vertex"].properties)
    assert not data.text and data.byte_order == "<"
    v = data["vertex"].data
    src = plyfile.PlyData.read(str(lite_ply))["vertex"].data
    for name in model.COLUMNS:
        assert np.array_equal(v[name], src[name])
    assert not v["nx"].any()


def test_3dgs_to_lite_ply_keeps_values(tmp_path, gs_ply):
    out = tmp_path / "lite.ply"
    splatconv.convert(gs_ply, out, layout="lite")
    scene = splatconv.read(out)
    assert scene.variant == model.VARIANT_LITE
    assert np.array_equal(scene.columns["scale_2"], splatconv.read(gs_ply).columns["scale_2"])


def _with_list_property(path, cols: dict, name: str, *, text: bool) -> str:
    """A PLY whose vertex element has a list property ``name`` besides ``cols``."""
    n = len(cols["x"])
    fields = [(k, "f4") for k in cols] + [(name, object)]
    arr = np.empty(n, dtype=fields)
    for k, v in cols.items():
        arr[k] = v
    for i in range(n):
        arr[name][i] = np.arange(i % 4, dtype=np.int32)
    element = plyfile.PlyElement.describe(arr, "vertex", len_types={name: "u1"}, val_types={name: "i4"})
    plyfile.PlyData([element], text=text).write(str(path))
    return str(path)


@pytest.mark.parametrize("text", [False, True])
def test_list_property_in_vertex_is_ignored_and_listed(tmp_path, text):
    cols = lite_columns_with_normals(random_columns(50, 8))
    path = _with_list_property(tmp_path / "list.ply", cols, "neighbours", text=text)
    scene = splatconv.read(path)
    assert scene.count == 50 and scene.variant == model.VARIANT_LITE
    assert scene.meta["ignored_properties"] == ["neighbours"]
    for name in model.COLUMNS:
        assert np.array_equal(scene.columns[name], cols[name]), name


def test_list_property_named_like_an_attribute_is_refused(tmp_path):
    cols = lite_columns_with_normals(random_columns(5, 8))
    del cols["opacity"]
    path = _with_list_property(tmp_path / "list.ply", cols, "opacity", text=False)
    with pytest.raises(UnsupportedError) as e:
        splatconv.read(path)
    assert "property opacity is a list, not one number a splat" in str(e.value)


#: Header lines, well and badly formed, that the grammar test below draws from.
_HEADER_LINES = ("format binary_little_endian 1.0", "format ascii 1.0", "format binary_big_endian 2.0",
                 "format foo 1.0", "format", "element vertex 0", "element face 0", "element vertex",
                 "element vertex 0 1", "property float x", "property f4 y",
                 "property list uchar float l", "property list uchar bogus l", "property bogus z", "property",
                 "property float", "property list uchar", "comment hi", "obj_info x", "", " ", "\t",
                 "end_header x", " end_header", "end_header ", "\x1c", "comment \xe9", "element v\xe9 0",
                 "property float x", "element vertex 0\x1c")


def _plyfile_verdict(head: bytes):
    """What plyfile says of a header whose counts are 0 (its rows are none): the reference for ours."""
    import io

    try:
        plyfile.PlyData.read(io.BytesIO(head))
    except plyfile.PlyHeaderParseError as e:
        return f"bad header: {e.message}", (f"line {e.line}",)
    except ValueError as e:
        return f"cannot parse: {e}", ()
    return None


@pytest.mark.parametrize("seed", range(40))
def test_header_grammar_is_plyfiles(seed):
    """The header parser accepts what plyfile accepts and names an error as plyfile does.

    plyfile is the reference here (the reader uses it only to name a bad ASCII
    row): random headers of well and badly formed lines, counts 0 so that
    plyfile reads no rows, every line ending plyfile knows.
    """
    import random

    from splatconv.formats import ply_container

    rng = random.Random(seed)
    for _ in range(25):
        lines = ["format binary_little_endian 1.0", "element vertex 0", "property float x", "end_header"]
        for _ in range(rng.randint(0, 3)):
            lines.insert(rng.randrange(len(lines) + 1), rng.choice(_HEADER_LINES))
        nl = rng.choice(["\n", "\r\n", "\r"])
        head = nl.join(["ply"] + lines).encode("latin-1") + nl.encode()
        header = ply_container.parse_header(head, "h.ply")
        if header.header_bytes is None:
            continue  # no end_header line: plyfile would read on into the rows
        ours = header.error and (header.error.message, header.error.where)
        # The header ends at its first end_header line (the body follows): plyfile is given that much.
        assert ours == _plyfile_verdict(head[:header.header_bytes]), head
