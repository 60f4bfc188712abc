"""Turn report data (from :mod:`splatconv.stats`) into text or JSON."""

from __future__ import annotations

import json


def to_json(data) -> str:
    """Stable JSON: fixed key order as built, two-space indent, no NaN constants."""
    return json.dumps(data, indent=2, allow_nan=False)


def _fmt_range(r) -> str:
    return "none finite" if r is None else f"{r[0]:.6g} .. {r[1]:.6g}"


def info_text(info: dict) -> str:
    """Human-readable ``info`` output, one fact per line."""
    lines = [
        f"file:      {info['path']} ({info['file_bytes']:,} bytes)",
        f"format:    {info['format']}" + (f" ({info['ply_format']})" if info.get("ply_format") else ""),
        f"variant:   {info['variant']}" + (f", colour read as {info['color']}" if info.get("color") else ""),
        f"count:     {info['count']:,} splats",
    ]
    tex = info["texture"]
    actual = tex["actual_bytes"]
    data = f"{tex['declared_bytes']:,} bytes declared" + (
        f", {actual:,} present" if actual is not None else " (when converted)")
    lines.append(f"texture:   {tex['width']} x {tex['height']} RGBA32UI, {data}")
    cams = info["cameras"]
    names = ", ".join(str(c["img_name"]) for c in cams[:4]) + (", ..." if len(cams) > 4 else "")
    lines.append(f"cameras:   {len(cams)}" + (f" ({names})" if cams else ""))
    lines.append(f"time:      centres {_fmt_range(info['time_range'])}, "
                 f"visible {_fmt_range(info['visible_time_range'])}")
    b = info["bounds"]
    if b is None:
        lines.append("bounds:    no finite positions")
    else:
        lo = ", ".join(f"{v:.4g}" for v in b["min"])
        hi = ", ".join(f"{v:.4g}" for v in b["max"])
        lines.append(f"bounds:    min ({lo})  max ({hi})")
    bad = {k: v for k, v in info["nonfinite"].items() if v}
    lines.append("nonfinite: " + (", ".join(f"{k} {v}" for k, v in bad.items()) if bad else "none"))
    if info.get("ignored_properties"):
        lines.append("ignored:   " + ", ".join(info["ignored_properties"]))
    if info.get("extra_elements"):
        lines.append("elements:  also " + ", ".join(info["extra_elements"]) + " (ignored)")
    if info.get("chunks") and len(info["chunks"]) > 1:
        lines.append("chunks:    " + ", ".join(f"{c['type']} ({c['size']:,} bytes)" for c in info["chunks"]))
    for note in info["notes"]:
        lines.append(f"note:      {note}")
    return "\n".join(lines)
