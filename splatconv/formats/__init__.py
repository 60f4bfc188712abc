"""One module per format behind one registry keyed by file suffix.

Every format module fills one declaration, ``FORMAT``, a
:class:`~splatconv.formats.base.Format`: its name and suffixes, what it can do
and how it stores a scene, and the functions that do it. Callers look one up
with :func:`format_for` (or, for the viewer's texture, :func:`texture_format`)
and read its fields; none of them names a format. Adding a format is adding a
module that ends with ``FORMAT = Format(...)`` and one line to ``FORMATS``. A
``.zst`` suffix after a format's suffix means the same format, zstd-compressed
(see :mod:`splatconv.zstd`). The player page is no format: :mod:`splatconv.publish`
writes it, asking these formats what the page plays (``check_playable``).
"""

from __future__ import annotations

import os

from ..errors import UsageError
from ..zstd import inner_name
from . import compressed_ply, gltf, ply, sog, splat, splatv, splatvq, spz
from .base import Format

#: Every format; a path's longest matching suffix chooses one (`_lookup`).
FORMATS: tuple[Format, ...] = (ply.FORMAT, splatv.FORMAT, splatvq.FORMAT, splat.FORMAT, spz.FORMAT,
                               compressed_ply.FORMAT, sog.FORMAT, gltf.FORMAT)
REGISTRY: dict[str, Format] = {suffix: fmt for fmt in FORMATS for suffix in fmt.suffixes}
#: The suffix of baked frames unless asked (``bake --frames``): PLY, what 3DGS tools and web viewers open.
FRAME_SUFFIX = ply.FORMAT.suffixes[0]

_TEXTURE = [fmt for fmt in FORMATS if fmt.stores_texture and fmt.can_write]
if len(_TEXTURE) != 1:  # pragma: no cover (a registry mistake, caught on import)
    raise TypeError("exactly one writable format must store the viewer's texture")


def _lookup(path: str) -> Format | None:
    """The format whose suffix ``path`` ends in (case-insensitive, after any ``.zst``), or None; the longest
    suffix wins (``x.compressed.ply`` before ``x.ply``)."""
    lower = inner_name(path).lower()
    found = [suffix for suffix in REGISTRY if lower.endswith(suffix)]
    return REGISTRY[max(found, key=len)] if found else None


def format_for(path: str | os.PathLike, *, purpose: str | None = None, also: tuple = ()) -> Format:
    """The format of ``path``, chosen by its (case-insensitive) suffix.

    Parameters
    ----------
    path : path
    purpose : {None, "read", "write"}
        Refuse a format that cannot be read (or written).
    also : tuple of str
        Suffixes of outputs the caller writes besides the formats (the player page's,
        :data:`splatconv.publish.PAGE`), named beside them when ``path`` has none of these.

    Raises
    ------
    UsageError
        For a suffix no format claims, or one that cannot serve ``purpose``.
    """
    path = os.fspath(path)
    fmt = _lookup(path)
    if fmt is None:
        known = ", ".join(sorted({*REGISTRY, *also}))
        raise UsageError(f"unknown file type (expected one of {known}, optionally + .zst)", path)
    if fmt.companions is not None and fmt.companions(inner_name(path)) and inner_name(path) != path:
        raise UsageError(f"a file with files beside it ({', '.join(fmt.companions(inner_name(path)))}) cannot be "
                         "zstd-compressed", path)
    if purpose == "read" and not fmt.can_read:
        raise UsageError(f"{fmt.name} files can be written, not read", path)
    if purpose == "write" and not fmt.can_write:
        raise UsageError(f"{fmt.name} files can be read, not written", path)
    return fmt


def texture_format() -> Format:
    """The format that stores the viewer's texture itself and can be written: what the viewer loads,
    and what any other scene becomes for it (``stats``' simulated conversion, drawing, the player)."""
    return _TEXTURE[0]


def compat_modes() -> tuple:
    """Every compat mode some format accepts, for option choices."""
    return tuple(sorted({mode for fmt in FORMATS for mode in fmt.compat_modes}))


def layouts() -> tuple:
    """Every record layout some format's writer offers, for option choices (first offered first)."""
    return tuple(dict.fromkeys(name for fmt in FORMATS for name in fmt.layouts))


def playable_format(quality: str) -> Format:
    """The format the player page plays as it is (``check_playable``) whose writer offers ``quality``:
    what a page at that quality is given.

    Raises
    ------
    UsageError
        When no such format offers ``quality``.
    """
    for fmt in playable_formats():
        if quality in fmt.qualities:
            return fmt
    raise UsageError(f"unknown quality {quality!r} (expected one of {', '.join(qualities())})")


def playable_formats() -> tuple:
    """The formats whose files the player page plays as they are (``check_playable``)."""
    return tuple(fmt for fmt in FORMATS if fmt.check_playable is not None)


def playable_qualities() -> tuple:
    """Every quality setting a format the page plays as it is offers (first offered first): the
    settings a page can embed a scene at."""
    return tuple(dict.fromkeys(name for fmt in playable_formats() for name in fmt.qualities))


def quantized_formats() -> tuple:
    """The formats whose writer offers quality settings (``qualities``): what ``stats`` measures a scene
    in at each setting."""
    return tuple(fmt for fmt in FORMATS if fmt.qualities)


def qualities() -> tuple:
    """Every quality setting some format's writer offers, for option choices (first offered first)."""
    return tuple(dict.fromkeys(name for fmt in FORMATS for name in fmt.qualities))
