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


def _psnr(v) -> str:
    return "inf" if v is None else f"{v:.2f}"


def frames_text(data: dict) -> str:
    """The per-frame table and verdict of ``verify`` / ``diff`` (from ``Outcome.as_dict``)."""
    lines = [f"{'time':>6}  {'camera':>6}  {'PSNR dB':>8}  {'max err':>7}  {'mean err':>8}  {'pixels off':>10}"]
    for f in data["frames"]:
        lines.append(f"{f['time']:>6.3f}  {f['camera']:>6}  {_psnr(f['psnr']):>8}  {f['max_abs_error']:>7}  "
                     f"{f['mean_abs_error']:>8.3f}  {100 * f['share_off']:>9.3f}%")
    if data["frames"]:
        lines.append(f"(errors out of 255; pixels off: a channel off by more than "
                     f"{data['frames'][0]['tolerance']})")
    return "\n".join(lines)


def structure_text(data: dict) -> str:
    """Per-attribute errors of ``verify``, against what quantization explains."""
    lines = [f"{'attribute':<10}  {'max abs err':>11}  {'max rel err':>11}  {'rmse':>10}  {'unexplained':>11}"]
    for name, g in data["structure"].items():
        lines.append(f"{name:<10}  {g['max_abs_error']:>11.4g}  {g['max_rel_error']:>11.4g}  {g['rmse']:>10.4g}  "
                     f"{g['unexplained']:>11,}")
    return "\n".join(lines)


def verdict_text(data: dict) -> str:
    """One closing line (more for failures) naming the worst frames and drifted attributes."""
    lines = []
    bad_frames = sorted((f for f in data["frames"] if f["psnr"] is not None and f["psnr"] < data["min_psnr"]),
                        key=lambda f: f["psnr"])
    for name, g in data.get("structure", {}).items():
        if g["unexplained"]:
            lines.append(f"FAIL: {name} drifted: {g['unexplained']:,} of {g['compared']:,} values off by more than "
                         f"quantization explains (max error {g['max_abs_error']:.4g}, relative "
                         f"{100 * g['max_rel_error']:.3g}%)")
    if bad_frames:
        worst = ", ".join(f"t={f['time']:g} camera {f['camera']} ({f['psnr']:.2f} dB)" for f in bad_frames[:3])
        lines.append(f"FAIL: {len(bad_frames)} of {len(data['frames'])} frames below {data['min_psnr']:g} dB; "
                     f"worst: {worst}")
    if not lines:
        w = data["worst"]
        worst = "" if w is None else f"; worst {_psnr(w['psnr'])} dB at t={w['time']:g} camera {w['camera']}"
        lines.append(f"PASS: {len(data['frames'])} frames at or above {data['min_psnr']:g} dB{worst}")
    return "\n".join(lines)
