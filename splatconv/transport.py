"""zstd transport: the size a web server sends with ``Content-Encoding: zstd``.

Compression and decompression stream through fixed-size buffers, so a large file
never sits in memory twice.
"""

from __future__ import annotations

import os

#: Default zstd level for reports and ``.zst`` output: 19, zstd's highest level
#: before the "ultra" ones, worth it for files served many times.
DEFAULT_LEVEL = 19
SUFFIX = ".zst"


class _Counter:
    """A write-only sink that only counts bytes."""

    def __init__(self):
        self.count = 0

    def write(self, data) -> int:
        n = len(data)
        self.count += n
        return n


def compressor(level: int = DEFAULT_LEVEL):
    import zstandard

    # threads=-1: one worker per core; the frame is the same format either way.
    return zstandard.ZstdCompressor(level=level, threads=-1, write_content_size=True)


def compressed_size(path: str | os.PathLike, level: int = DEFAULT_LEVEL) -> int:
    """Bytes of ``path`` compressed with zstd at ``level``, streamed, nothing written."""
    sink = _Counter()
    with open(path, "rb") as f:
        compressor(level).copy_stream(f, sink, size=os.fstat(f.fileno()).st_size)
    return sink.count


def compressed_size_of(chunks, level: int = DEFAULT_LEVEL) -> int:
    """Bytes of the concatenated byte chunks compressed with zstd at ``level``."""
    sink = _Counter()
    with compressor(level).stream_writer(sink, closefd=False) as w:
        for chunk in chunks:
            w.write(chunk)
    return sink.count
