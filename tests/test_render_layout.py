"""The float reference texel table (render/layout.py) against specs/render.md, fetch_float.glsl and the viewer."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from splatconv import viewer
from splatconv.model import Scene
from splatconv.render import layout
from splatconv.render.preview import shader_source
from tests.conftest import random_columns

SPEC = (Path(__file__).resolve().parent.parent / "specs" / "render.md").read_text(encoding="utf-8")

#: The Splat struct's fields (splat_head.glsl) and the values they hold, by float_record name.
SPLAT_FIELDS = {
    "center": ("x", "y", "z"),
    "rot": ("rot_0", "rot_1", "rot_2", "rot_3"),
    "scale": ("scale_0", "scale_1", "scale_2"),
    "rgba": ("f_dc_0", "f_dc_1", "f_dc_2", "opacity"),
    "vel": ("motion_0", "motion_1", "motion_2"),
    "acc": ("motion_3", "motion_4", "motion_5"),
    "jerk": ("motion_6", "motion_7", "motion_8"),
    "omega": ("omega_0", "omega_1", "omega_2", "omega_3"),
    "trbf": ("trbf_center", "trbf_scale"),
}
#: What the spec's function words mean, on the float64 column.
FUNCTIONS = {
    "": lambda v: v,
    "exp": np.exp,
    "clamp": lambda v: np.clip(v, 0.0, 1.0),
    "sigmoid": lambda v: 1.0 / (1.0 + np.exp(-v)),
}


def spec_table() -> list:
    """The spec's rows: for each texel, four (function, name) cells; name None for 0."""
    section = SPEC[SPEC.index("## The float reference texture"):]
    section = section[:section.index("\n## ")]
    rows = re.findall(r"^\| (\d+) \|(.+)\|$", section, re.M)
    assert [int(k) for k, _ in rows] == list(range(len(rows)))
    table = []
    for _, cells in rows:
        parsed = []
        for cell in cells.split("|"):
            words = cell.split()
            if words == ["0"]:
                parsed.append(("", None))
            else:
                parsed.append(("", words[0]) if len(words) == 1 else (words[0], words[1]))
        table.append(parsed)
    return table


def test_spec_table_is_the_layout():
    table = spec_table()
    assert [tuple(name for _, name in row) for row in table] == list(layout.FLOAT_TEXELS)
    assert "8 texels per splat (`FLOAT_TEXELS_PER_SPLAT`), 512 splats\nper row (`FLOAT_SPLATS_PER_ROW`)" in SPEC
    assert (layout.FLOAT_TEXELS_PER_SPLAT, layout.FLOAT_SPLATS_PER_ROW) == (8, 512)


def test_spec_functions_are_what_float_attributes_computes():
    cols = random_columns(2000, seed=3)
    cols["f_dc_0"] = (cols["f_dc_0"] * 3 - 1).astype(np.float32)  # outside [0, 1]: the clamp matters
    rows = layout.float_attributes(Scene(columns=cols))
    for k, row in enumerate(spec_table()):
        for c, (function, name) in enumerate(row):
            got = rows[:, 4 * k + c]
            if name is None:
                assert not got.any()
            else:
                expected = FUNCTIONS[function](cols[name].astype(np.float64)).astype(np.float32)
                np.testing.assert_array_equal(got, expected, err_msg=f"texel {k}.{'xyzw'[c]}: {function} {name}")


def _components(expr: str) -> list:
    """``t0.xyz``, ``vec3(t4.w, t5.xy)``, ``t1`` -> [(texel, component), ...]."""
    inner = re.fullmatch(r"(?:vec\d\((.*)\)|(.*))", expr.strip())
    out = []
    for part in (inner.group(1) or inner.group(2)).split(","):
        m = re.fullmatch(r"\s*t(\d)(?:\.([xyzw]+))?\s*", part)
        out.extend((int(m.group(1)), "xyzw".index(ch)) for ch in (m.group(2) or "xyzw"))
    return out


def test_fetch_float_glsl_reads_the_layout():
    glsl = shader_source("fetch_float.glsl")
    read = {}
    assignments = re.findall(r"s\.(\w+) = (.+?);", glsl)
    assert {field for field, _ in assignments} == set(SPLAT_FIELDS)
    for field, expr in assignments:
        places = _components(expr)
        assert len(places) == len(SPLAT_FIELDS[field]), field
        for (k, c), name in zip(places, SPLAT_FIELDS[field]):
            read[(k, c)] = name
    declared = {(k, c): name for k, names in enumerate(layout.FLOAT_TEXELS) for c, name in enumerate(names) if name}
    assert read == declared
    # The texel address: FLOAT_TEXELS_PER_SPLAT texels a splat, FLOAT_SPLATS_PER_ROW splats a row.
    per_row = layout.FLOAT_SPLATS_PER_ROW
    assert f"((i & {hex(per_row - 1)}) << {layout.FLOAT_TEXELS_PER_SPLAT.bit_length() - 1}) | k" in glsl
    assert f"i >> {per_row.bit_length() - 1}" in glsl
    assert 1 << (layout.FLOAT_TEXELS_PER_SPLAT.bit_length() - 1) == layout.FLOAT_TEXELS_PER_SPLAT


def test_float_attributes_order_padding_and_float_record():
    cols = random_columns(70_000, seed=5)  # more than one conversion chunk
    scene = Scene(columns=cols)
    order = np.random.default_rng(0).permutation(scene.count)
    rows = layout.float_attributes(scene, order, records=layout.texture_records(scene.count))
    assert rows.shape == (69 * 1024, layout.FLOAT_WORDS) and rows.dtype == np.float32
    assert not rows[scene.count:].any()
    record = viewer.float_record({k: v[order] for k, v in cols.items()})
    for name, column in layout.FLOAT_COLUMN.items():
        np.testing.assert_array_equal(rows[:scene.count, column], record[name].astype(np.float32), err_msg=name)


def test_float_attributes_of_nonfinite_values_raise_no_warning():
    cols = random_columns(10)
    cols["scale_0"][:3] = [np.inf, np.nan, 1000.0]  # exp(1000) overflows float32 and float64
    cols["opacity"][:2] = [-np.inf, np.nan]
    rows = layout.float_attributes(Scene(columns=cols))
    s0 = rows[:3, layout.FLOAT_COLUMN["scale_0"]]
    assert s0[0] == np.inf and np.isnan(s0[1]) and s0[2] == np.inf
    op = rows[:2, layout.FLOAT_COLUMN["opacity"]]
    assert op[0] == 0 and np.isnan(op[1])


def test_every_value_the_shader_reads_has_one_place():
    names = [n for row in layout.FLOAT_TEXELS for n in row if n]
    assert len(names) == len(set(names))
    assert set(names) == set(viewer.float_record(random_columns(1)))
    assert all(len(row) == 4 for row in layout.FLOAT_TEXELS)
