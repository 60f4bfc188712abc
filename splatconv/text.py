"""What a command prints: findings (the data of ``info``, ``stats``, ``verify``, ``diff``, a frame sequence's fit,
``merge --segments``; keys in specs/json.md) as text, Markdown or JSON.

Words used across the package: a *report* is what one step did to a scene
(:class:`splatconv.ops.report.OpReport`, ``WriteReport``: counts and ``notes``);
*findings* are what a command found, as JSON-able data (:func:`splatconv.stats.stats_findings`,
:func:`splatconv.stats.describe`); this module gives findings their *text*.
"""

from __future__ import annotations

import json
import textwrap

from .wording import kinds_text, plural


def to_json(data) -> str:
    """Stable JSON: fixed key order as built, two-space indent, no NaN constants."""
    return json.dumps(data, indent=2, allow_nan=False)


def _fmt_range(r) -> str:
    if r is None:
        return "none finite"
    return " .. ".join(f"{v:.6g}" for v in r)


def _visible_text(info: dict) -> str:
    """When the viewer draws some splat: the union of the splats' visible intervals."""
    r, always = info["visible_time_range"], info.get("visible_always", 0)
    if r is None:
        return "never (no splat has a finite time centre)"
    if None in r:  # some splat is drawn at every time: the union has no end
        return f"at every time ({plural(always, 'splat')} with an infinite temporal scale)"
    return _fmt_range(r)


def _detail_text(value) -> str:
    if isinstance(value, list):
        return ", ".join(_detail_text(v) for v in value) if value else "none"
    if isinstance(value, dict):
        return " ".join(f"{k} {_detail_text(v)}" for k, v in value.items())
    return str(value)


def undrawable_text(counts: dict, total: int) -> str:
    """Undrawable splats by kind (``{kind: count}``) out of ``total``, in words; "none" when there are none."""
    n = sum(counts.values())
    if not n:
        return "none"
    return (f"{n:,} of {plural(total, 'splat')} ({100 * n / total:.3g}%) the viewer can never draw: "
            f"{kinds_text(counts)}")


def info_text(info: dict) -> str:
    """Human-readable ``info`` output, one fact per line."""
    details = dict(info["details"])
    ply_format, color = details.pop("ply_format", None), details.pop("color", None)
    lines = [
        f"file:      {info['path']} ({plural(info['file_bytes'], 'byte')}"
        + (f", {info['compressed_bytes']:,} zstd-compressed)" if info.get("compressed_bytes") else ")"),
        f"format:    {info['format']}" + (f" ({ply_format})" if ply_format else ""),
        f"variant:   {info['variant']}" + (f", colour read as {color}" if color else ""),
        f"count:     {plural(info['count'], 'splat')}",
    ]
    tex = info["texture"]
    actual = tex["actual_bytes"]
    data = f"{tex['declared_bytes']:,} bytes declared" + (
        f", {actual:,} present" if actual is not None else " (when converted)")
    if actual is not None and actual < tex["declared_bytes"]:
        data += " (not padded: the rest reads as zeros)"
    lines.append(f"texture:   {tex['width']} x {tex['height']} RGBA32UI, {data}")
    cams = info["cameras"]
    names = ", ".join(str(c["img_name"]) for c in cams[:4]) + (", ..." if len(cams) > 4 else "")
    lines.append(f"cameras:   {len(cams)}" + (f" ({names})" if cams else ""))
    lines.append(f"time:      centres {_fmt_range(info['time_range'])}, visible {_visible_text(info)}")
    b = info["bounds"]
    if b is None:
        lines.append("bounds:    no finite positions")
    else:
        lo = ", ".join(f"{v:.4g}" for v in b["min"])
        hi = ", ".join(f"{v:.4g}" for v in b["max"])
        lines.append(f"bounds:    min ({lo})  max ({hi})")
    bad = {k: v for k, v in info["nonfinite"].items() if v}
    lines.append("nonfinite: " + (", ".join(f"{k} {v:,}" for k, v in bad.items()) if bad else "none"))
    if info["flat"]:
        lines.append(f"flat:      {plural(info['flat'], 'splat')} with a zero scale (log scale -inf), drawn flat")
    lines.append("undrawable: " + undrawable_text(info["undrawable"], info["count"]))
    ignored, extra = details.pop("ignored_properties", None), details.pop("extra_elements", None)
    if ignored:
        lines.append("ignored:   " + ", ".join(ignored))
    if extra:
        lines.append("elements:  also " + ", ".join(extra) + " (ignored)")
    chunks = details.pop("chunks", None)
    if chunks and len(chunks) > 1:
        lines.append("chunks:    " + ", ".join(f"{c['type']} ({plural(c['size'], 'byte')})" for c in chunks))
    for key, value in details.items():  # a format's other facts, as they come
        lines.append(f"{key + ':':<10} {_detail_text(value)}")
    for note in info["notes"]:
        lines.append(f"note:      {note}")
    return "\n".join(lines)


def _psnr(v) -> str:
    return "inf" if v is None else f"{v:.2f}"


def _frames_footnote(frames: list) -> str:
    why = f"(errors out of 255; pixels off: a channel off by more than {frames[0]['tolerance']}"
    if any(f["identical"] for f in frames):
        why += "; inf: the two frames are identical"
    return why + ")"


def frames_text(data: dict) -> str:
    """The per-frame table of ``verify`` / ``diff`` of scene files (from ``Outcome.as_dict``)."""
    lines = [f"{'time':>6}  {'camera':>6}  {'PSNR dB':>8}  {'max err':>7}  {'mean err':>8}  {'pixels off':>10}"]
    for f in data["frames"]:
        lines.append(f"{f['time']:>6.3f}  {f['camera']:>6}  {_psnr(f['psnr']):>8}  {f['max_abs_error']:>7}  "
                     f"{f['mean_abs_error']:>8.3f}  {100 * f['share_off']:>9.3f}%")
    if data["frames"]:
        lines.append(_frames_footnote(data["frames"]))
    return "\n".join(lines)


#: What an attribute line says in place of errors, for a storage kind not checked value by value
#: (:data:`splatconv.compare.UNCHECKED`).
_UNCHECKED_WORDS = {"none": "not stored by CONVERTED (a static format)",
                    "quantized": "quantized by CONVERTED past a value-by-value check"}


def attributes_text(data: dict) -> str:
    """Per-attribute errors of ``verify`` (its ``attributes`` block), against what quantization explains."""
    lines = [f"{'attribute':<10}  {'max abs err':>11}  {'max rel err':>11}  {'rmse':>10}  {'unexplained':>11}"]
    for name, g in data["attributes"].items():
        if g["storage"] in _UNCHECKED_WORDS:
            lines.append(f"{name:<10}  {_UNCHECKED_WORDS[g['storage']]}: the frames check it")
            continue
        lines.append(f"{name:<10}  {g['max_abs_error']:>11.4g}  {g['max_rel_error']:>11.4g}  {g['rmse']:>10.4g}  "
                     f"{g['unexplained']:>11,}")
    lines.append("(errors between values finite on both sides, in the viewer's units)")
    for name, g in data["attributes"].items():
        if g["nan_stored"]:
            lines.append(f"{name}: {plural(g['nan_stored'], 'NaN value')} stored as numbers "
                         f"(a byte cannot hold NaN)")
    return "\n".join(lines)


def _drift_text(name: str, g: dict) -> str:
    """What drifted in one attribute: values made infinite, non-finite values changed, the rest."""
    parts = []
    of = f"of {plural(g['values'], 'value')}"
    if g["became_infinite"]:
        parts.append(f"{g['became_infinite']:,} {of} became infinite (finite in the source)")
    if g["nonfinite_changed"]:
        parts.append(f"{g['nonfinite_changed']:,} {'' if parts else of + ' '}that were NaN or infinite in the "
                     f"source were stored as something else")
    off = g["unexplained"] - g["became_infinite"] - g["nonfinite_changed"]
    if off:
        parts.append(f"{off:,} {'more' if parts else of} off by more than quantization explains (largest error "
                     f"between finite values {g['max_abs_error']:.4g}, relative {100 * g['max_rel_error']:.3g}%)")
    return f"FAIL: {name} drifted: " + "; ".join(parts)


def verdict_text(data: dict) -> str:
    """One closing line (more for failures) naming the worst frames and drifted attributes."""
    lines = []
    bad_frames = sorted((f for f in data["frames"] if f["psnr"] is not None and f["psnr"] < data["min_psnr"]),
                        key=lambda f: f["psnr"])
    for name, g in (data.get("attributes") or {}).items():
        if g["unexplained"]:
            lines.append(_drift_text(name, g))
    if bad_frames:
        worst = ", ".join(f"t={f['time']:g} camera {f['camera']} ({f['psnr']:.2f} dB)" for f in bad_frames[:3])
        lines.append(f"FAIL: {len(bad_frames):,} of {plural(len(data['frames']), 'frame')} below "
                     f"{data['min_psnr']:g} dB; worst: {worst}")
    if not lines:
        w = data["worst"]
        worst = "" if w is None else f"; worst {_psnr(w['psnr'])} dB at t={w['time']:g} camera {w['camera']}"
        lines.append(f"PASS: {plural(len(data['frames']), 'frame')} at or above {data['min_psnr']:g} dB{worst}")
    return "\n".join(lines)


# --------------------------------------------------------------------------
# ``stats``: the same tables as aligned text or Markdown.


def _num(v, fmt="{:,}") -> str:
    return "-" if v is None else fmt.format(v)


def _g(v) -> str:
    return "-" if v is None else f"{v:.4g}"


#: Columns the human ``stats`` output fits in.
TEXT_WIDTH = 100
#: Stands for the middle of a path too long for the text table.
_ELISION = "..."
#: Characters of an elided path kept, at least.
_MIN_PATH = 12


def _elide(text: str, width: int) -> str:
    """``text`` cut to ``width`` characters by replacing its middle (more of the end is kept)."""
    if len(text) <= width:
        return text
    keep = max(width - len(_ELISION), 2)
    head = keep // 3
    return text[:head] + _ELISION + text[len(text) - (keep - head):]


def _stats_tables(data: dict) -> list:
    """(title, headers, rows, left-aligned columns) tables of ``stats`` findings; paths in full."""
    tables = []
    level = data["files"][0]["zstd_level"]
    rows = []
    for f in data["files"]:
        name = f["path"] if f["path"] is not None else "(as converted)"
        rows.append([f["role"], name, _num(f["bytes"]), _num(f["bytes_per_splat"], "{:,.2f}"),
                     _num(f["zstd_bytes"]), _num(f["ratio"], "{:.3f}"), _num(f["zstd_ratio"], "{:.3f}")])
    tables.append(("files", ["file", "path", "bytes", "B/splat", f"zstd-{level}", "ratio", "zstd ratio"], rows, 2))
    for name in dict.fromkeys(q["format"] for q in data.get("quantized") or ()):
        rows = [[q["quality"], _num(q["splats"]), _num(q["bytes"]), _num(q["bytes_per_splat"], "{:,.2f}"),
                 _num(q["ratio"], "{:.3f}")] for q in data["quantized"] if q["format"] == name]
        tables.append((f"{name}, each setting (encoded in memory; B/splat: per drawable splat, the only ones held)",
                       ["setting", "splats", "bytes", "B/splat", "ratio"], rows, 1))
    m = data["motion"]
    d = data["described"]
    per_unit = d["omega"] == "per unit quaternion"
    title = (f"motion and rotation speed of {_role(d['role'])}'s drawable splats (per unit time"
             + ("; omega per unit quaternion)" if per_unit else ")"))
    tables.append((title, ["magnitude", "p50", "p90", "p99", "max"],
                   [[k, _g(v["p50"]), _g(v["p90"]), _g(v["p99"]), _g(v["max"])] for k, v in m.items()], 1))
    if data["attributes"] is not None:
        keys = ["max_abs_error", "max_rel_error", "rmse", "nonfinite", "overflow", "underflow", "subnormal",
                "clamped"]
        heads = ["attribute", "max abs err", "max rel err", "rmse", "nonfinite", "overflow", "underflow",
                 "subnormal", "clamped"]
        rows = [[g] + [_g(a[k]) if k in keys[:3] else _num(a[k]) for k in keys]
                for g, a in data["attributes"].items()]
        title = ("attributes (the conversion against source, in viewer units)" if data["files"][-1]["path"] is None
                 else "attributes (converted against source, in viewer units)")
        tables.append((title, heads, rows, 1))
    return tables


def _role(role: str) -> str:
    """SOURCE or CONVERTED, as the command line names its arguments."""
    return role.upper()


def _file_name(f: dict) -> str:
    return f["path"] if f["path"] is not None else "(as converted, in memory)"


def _summary_lines(data: dict) -> list:
    """Summary lines, each naming the file it describes (SOURCE or CONVERTED)."""
    d = data["described"]
    of = f"({_role(d['role'])})"
    counts = "; ".join(f"{_role(f['role'])} {_file_name(f)}: {plural(data['count'] if f['role'] == 'source' else d['count'], 'splat')}"
                       for f in data["files"])
    lines = [f"count: {counts}",
             f"undrawable {of}: " + undrawable_text(data["undrawable"], d["count"])]
    if data["attributes"] is None:
        source = data["files"][0]
        why = ("SOURCE holds no splats" if data["count"] == 0
               else f"SOURCE alone is a {source['format']} file, which the viewer loads as stored")
        lines.append(f"attributes: none compared ({why})")
    p = data.get("pairing")
    if p and p["unpaired"]:
        lines.append(f"pairing: {p['unpaired']:,} of CONVERTED's {plural(p['paired'] + p['unpaired'], 'splat')} have no "
                     "splat of their colour left in SOURCE (nor as many of SOURCE's in CONVERTED): left out of the "
                     "errors above")
    b = data["bounds"]
    if b:
        lo = ", ".join(f"{v:.4g}" for v in b["min"])
        hi = ", ".join(f"{v:.4g}" for v in b["max"])
        lines.append(f"bounds {of}: min ({lo}) max ({hi})")
    t = data["time"]
    vis = t["visible"]
    lo_i, hi_i = vis.index(min(vis)), vis.index(max(vis))
    if min(vis) == max(vis):
        lines.append(f"time {of}: {len(vis)} steps over [0, 1]: {plural(min(vis), 'splat')} drawn at each")
    else:
        lines.append(f"time {of}: {len(vis)} steps over [0, 1]: {min(vis):,} to {plural(max(vis), 'splat')} drawn "
                     f"(fewest at t={t['times'][lo_i]:.3g}, most at t={t['times'][hi_i]:.3g})")
    v = data["viewer"]
    fits = ", ".join(f"{k}: {'yes' if ok else 'NO'}" for k, ok in v["fits_max_texture_size"].items())
    lines.append(f"viewer ({_role(v['role'])}): texture 4096x{v['texture_height']} (fits {fits}); "
                 f"cameras {v['cameras']}{' (EMPTY: the viewer needs one)' if v['empty_cameras'] else ''}; "
                 f"NaN positions {v['nan_positions']:,}")
    dmg = v.get("splatv_js_damage")
    if dmg is not None:
        hurt = [f"{g}: {d['infinity']:,} to infinity, {d['garbled']:,} garbled" for g, d in dmg.items()
                if d["infinity"] or d["garbled"]]
        why = (" (garbled: a nonzero half written where the nearest half is zero)"
               if any(d["garbled"] for d in dmg.values()) else "")
        lines.append("splaTV's own converter would corrupt in SOURCE: " + ("; ".join(hurt) if hurt else "nothing") + why)
    return lines


def _aligned(heads: list, rows: list, left: int, elide: int | None = None) -> list:
    """Aligned table lines that fit :data:`TEXT_WIDTH` columns.

    Column ``elide`` (a path) is shortened to the room the others leave; when
    that is not enough, the gap between columns narrows from two spaces to one,
    and then numbers lose their thousands separators.
    """
    for gap, plain in ((2, False), (1, False), (1, True)):
        table = [heads] + [[str(c).replace(",", "") if plain and i >= left else str(c) for i, c in enumerate(r)]
                           for r in rows]
        widths = [max(len(c) for c in col) for col in zip(*table)]
        if elide is not None:
            room = TEXT_WIDTH - 2 - gap * (len(widths) - 1) - sum(widths) + widths[elide]
            widths[elide] = min(widths[elide], max(room, _MIN_PATH, len(heads[elide])))
        if 2 + gap * (len(widths) - 1) + sum(widths) <= TEXT_WIDTH:
            break
    lines = []
    for r in table:
        cells = [_elide(c, w) if i == elide else c for i, (c, w) in enumerate(zip(r, widths))]
        cells = [c.ljust(w) if i < left else c.rjust(w) for i, (c, w) in enumerate(zip(cells, widths))]
        lines.append("  " + (" " * gap).join(cells).rstrip())
    return lines


def stats_text(data: dict) -> str:
    """Compact aligned tables of ``stats`` findings, every line within :data:`TEXT_WIDTH` columns.

    Paths too long for the files table lose their middle (``--json`` keeps them
    whole); summary lines wrap.
    """
    out = []
    for title, heads, rows, left in _stats_tables(data):
        out.append(title + ":")
        out.extend(_aligned(heads, rows, left, elide=heads.index("path") if "path" in heads else None))
        out.append("")
    for line in _summary_lines(data):
        out.extend(textwrap.wrap(line, TEXT_WIDTH, subsequent_indent="  ", break_on_hyphens=False))
    return "\n".join(out)


def stats_markdown(data: dict) -> str:
    """``stats`` findings as Markdown tables, for a pull request."""
    out = []
    for title, heads, rows, left in _stats_tables(data):
        out.append(f"**{title}**\n")
        out.append("| " + " | ".join(heads) + " |")
        out.append("|" + "|".join("---" if i < left else "---:" for i in range(len(heads))) + "|")
        for r in rows:
            out.append("| " + " | ".join(str(c).replace("|", "\\|") for c in r) + " |")
        out.append("")
    out.extend(f"- {line}" for line in _summary_lines(data))
    return "\n".join(out)


def images_text(data: dict) -> str:
    """The table of an image-vs-image ``diff`` (from ``Outcome.as_dict``): names, no time or camera;
    the shape matches :func:`frames_text`."""
    rows = [(f["a"], f["b"], f) for f in data["frames"]]
    wa = max([1] + [len(a) for a, _, _ in rows])
    wb = max([1] + [len(b) for _, b, _ in rows])
    lines = [f"{'A':<{wa}}  {'B':<{wb}}  {'PSNR dB':>8}  {'max err':>7}  {'mean err':>8}  {'pixels off':>10}"]
    for a, b, f in rows:
        lines.append(f"{a:<{wa}}  {b:<{wb}}  {_psnr(f['psnr']):>8}  {f['max_abs_error']:>7}  "
                     f"{f['mean_abs_error']:>8.3f}  {100 * f['share_off']:>9.3f}%")
    if rows:
        lines.append(_frames_footnote(data["frames"]))
    return "\n".join(lines)


def images_verdict_text(data: dict) -> str:
    """The closing PASS / FAIL line of an image-vs-image ``diff``."""
    bad = [f for f in data["frames"] if f["psnr"] is not None and f["psnr"] < data["min_psnr"]]
    word, relation = ("FAIL", "below") if bad else ("PASS", "at or above")
    w = data["worst"]
    return f"{word}: {w['a']} vs {w['b']}: {_psnr(w['psnr'])} dB, {relation} {data['min_psnr']:g} dB"


def _dist(d: dict, fmt: str) -> str:
    return "  ".join(f"{k} {fmt.format(d[k])}" for k in ("p50", "p90", "p99", "max"))


def sequence_text(data: dict) -> str:
    """A frame-sequence fit (:class:`splatconv.ops.sequence.SequenceReport` as a dict) as text."""
    n = data["frames"]
    times = data["times"]
    span = f"t {times[0]:g}" + (f" .. {times[-1]:g}" if len(times) > 1 else "")
    if not data["same_splats"]:
        per = data["splats_per_frame"]
        return (f"{plural(n, 'frame')} ({span}), different splats per frame: {plural(sum(per), 'splat')}, each frame shown "
                "around its own time")
    lines = [f"{plural(n, 'frame')} ({span}), the same {plural(data['splats_per_frame'][0], 'splat')} in each: motion fitted"]
    lines.append(f"  position error ({data['max_error']:.3g} allowed): {_dist(data['position_error'], '{:.3g}')}")
    lines.append(f"  rotation error (degrees):  {_dist(data['rotation_error_deg'], '{:.3g}')}")
    lines.append(f"  opacity error:             {_dist(data['opacity_error'], '{:.3g}')}")
    if data["split_splats"]:
        lines.append(f"  split into pieces: {plural(data['split_splats'], 'splat')}, {data['pieces_added']:+,} splats")
    return "\n".join(lines)


def _db(v) -> str:
    return "identical" if v is None else f"{v:.2f} dB"


def _nth(k: int) -> str:
    """1 -> 'frame', 2 -> '2nd frame', 11 -> '11th frame'."""
    if k == 1:
        return "frame"
    suffix = "th" if 10 <= k % 100 <= 20 else {1: "st", 2: "nd", 3: "rd"}.get(k % 10, "th")
    return f"{k}{suffix} frame"


def segments_text(data: dict) -> str:
    """``merge --segments``'s findings (:func:`splatconv.jobs.segments.segments_findings`) as text."""
    lines = [f"{len(data['segments'])} segments on one timeline: {plural(data['splats_in'], 'splat')} -> "
             f"{data['splats_out']:,} ("
             + (f"{data['ratio']:.2f}x; " if data["ratio"] is not None else "")
             + f"budget {data['budget']:g}x), "
             f"long-lived splats fade over {plural(data['leak_frames'], 'frame')} of the neighbours"]
    for i, s in enumerate(data["segments"]):
        given = sorted(s["pieces_per_long_lived"].items(), key=lambda kv: int(kv[0]))
        pieces = ", ".join(f"{n:,} x {k}" for k, n in given)
        lines.append(f"  segment {i}: frames {s['first_frame']}..{s['first_frame'] + s['frames'] - 1} "
                     f"(t {s['start']:.4f}..{s['end']:.4f}), {s['splats_in']:,} -> {plural(s['splats_out'], 'splat')}, "
                     f"{s['long_lived']:,} long-lived" + (f" (pieces: {pieces})" if pieces else "")
                     + (f", {s['dropped']:,} dropped" if s["dropped"] else ""))
    check = data.get("check")
    if check and check["rule"] != "none":
        how = ("a sample: evenly spread and both sides of the hand-overs; --check-every 1 for all"
               if check["rule"] == "sample" else f"every {_nth(check['every'])}")
        lines.append(f"checked {len(check['frames']):,} of {plural(check['of'], 'output frame')} ({how})")
    frames = data.get("frames") or []
    if frames:
        lines.append("frame  time      segment  local    PSNR vs the segment alone")
        for f in frames:
            lines.append(f"{f['frame']:5d}  {f['time']:.5f}  {f['segment']:7d}  {f['local_time']:.4f}  "
                         f"{_db(f['psnr'])}")
        s = data["fidelity"]
        lines.append(f"fidelity over {plural(s['frames'], 'frame')}: median {_db(s['median_psnr'])}, "
                     f"min {_db(s['min_psnr'])}; {s['below_40']} below 40 dB, {s['below_30']} below 30 dB")
    out = data.get("output")
    if out:
        lines.append(f"wrote {out['path']}: {plural(out['splats'], 'splat')}, {out['bytes']:,} bytes")
    return "\n".join(lines)
