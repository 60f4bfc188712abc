"""``convert`` to a compressed output that proves its quality: candidates at each precision step, measured,
the one that holds written.

``convert OUT.splatvq --min-psnr DB`` and ``--max-bytes SIZE``: each candidate is
written in full to a temporary folder, read back as any reader would, and drawn
against the scene it encodes (:mod:`splatconv.render.proof`); the output is then
the very bytes that were measured.
"""

from __future__ import annotations

import os
import shutil
import tempfile

from ..errors import OutputError, UsageError
from ..files.output import atomic_writer
from ..formats import format_for
from ..io import check_write_options, read, write
from ..model import Scene
from ..progress import SILENT
from ..ops.prune import leave_out
from ..publish import PAGE
from ..render.proof import proof_views, prove, ranked
from ..wording import plural
from .convert import convert

#: Coarser steps tried below the first that holds, to spend fewer bytes (each costs a proof).
MAX_COARSER = 2
#: Candidates ``--prune`` proves at most, and the share of the drawable splats it stops at (1/128).
PRUNE_PROOFS = 7
PRUNE_RESOLUTION = 128


def check_proof_options(output, min_psnr: float | None, max_bytes: int | None, prune: bool = False) -> None:
    """Refuse ``--min-psnr`` and ``--max-bytes`` for an output whose format has no precision steps, and
    ``prune`` without ``min_psnr``."""
    if prune and min_psnr is None:
        raise UsageError("--prune goes with --min-psnr: it leaves out splats while the floor holds")
    if min_psnr is None and max_bytes is None:
        return
    if not check_write_options(output, also=(PAGE,)).precisions:
        raise UsageError("--min-psnr and --max-bytes apply to outputs whose format has precision steps "
                         "(.splatvq)", output)
    if min_psnr is not None and not min_psnr > 0:
        raise UsageError(f"--min-psnr must be a positive number of dB, got {min_psnr:g}")
    if max_bytes is not None and max_bytes <= 0:
        raise UsageError(f"--max-bytes must be a positive size, got {max_bytes}")


def convert_proven(source, output, *, min_psnr: float | None, max_bytes: int | None, best_effort: bool = False,
                   prune: bool = False, **options):
    """:func:`splatconv.jobs.convert.convert` whose output proves its quality (:func:`write_proven`).

    The proof's options are checked before anything is read.
    """
    check_proof_options(output, min_psnr, max_bytes, prune)

    def writer(scene, out, **write_options):
        return write_proven(scene, out, min_psnr=min_psnr, max_bytes=max_bytes, best_effort=best_effort,
                            prune=prune, **write_options)

    return convert(source, output, writer=writer, **options)


class _Candidates:
    """Candidate files of one output, each written once to a temporary folder and measured once.

    A candidate is a precision step and a number of splats left out: the first
    that many of ``ranked`` (drawable rows, least contributing first).
    """

    def __init__(self, scene: Scene, path: str, views: list, options: dict, advance):
        self.scene, self.path, self.views, self.options, self.advance = scene, path, views, options, advance
        self.ranked = None
        self.sizes, self.proofs = {}, {}
        self.on_disk = None, None, None  # the candidate the file holds, its write report, its pruning report

    def put(self, key) -> tuple:
        """Write candidate ``key`` (step, left out) unless the file holds it: its write and pruning reports."""
        if self.on_disk[0] != key:
            step, left_out = key
            scene, pruned = self.scene, None
            if left_out:
                scene, pruned = leave_out(self.scene, self.ranked[:left_out], of=len(self.ranked))
            self.on_disk = key, write(scene, self.path, precision=step, force=True, **self.options), pruned
            self.sizes[key] = os.path.getsize(self.path)
        return self.on_disk[1:]

    def size(self, key) -> int:
        if key not in self.sizes:
            self.put(key)
        return self.sizes[key]

    def proof(self, key):
        if key not in self.proofs:
            self.put(key)
            self.proofs[key] = prove(self.scene, read(self.path), self.views)
            self.advance()
        return self.proofs[key]


def write_proven(scene: Scene, output, *, quality: str | None, min_psnr: float | None, max_bytes: int | None,
                 best_effort: bool = False, prune: bool = False, sort: str | None = None,
                 zstd_level: int | None = None, force: bool = False, progress=SILENT):
    """Write ``scene`` to ``output`` at the precision step that meets ``min_psnr`` within ``max_bytes``.

    Without ``max_bytes``, steps are tried from the setting as named (0) finer
    until the worst frame reaches ``min_psnr``, then up to :data:`MAX_COARSER`
    coarser while it still does (a frame can be worse at a finer step: the
    viewer's depth sort makes a large splat's small move show). With
    ``max_bytes``, the finest step that fits is tried first, then coarser ones.

    With ``prune`` (and ``min_psnr``), at the step chosen so, the drawable splats
    that add least to the proof's frames (:func:`splatconv.render.proof.ranked`)
    are left out, as many as a bisection of :data:`PRUNE_PROOFS` candidates finds
    while the worst frame still reaches ``min_psnr``.

    Returns
    -------
    (WriteReport, list of str)
        The candidate's write report and the notes that say what was pruned and proved.

    Raises
    ------
    OutputError
        Nothing fits ``max_bytes``, or no step reaches ``min_psnr`` (unless
        ``best_effort``, which writes the best measured and says how far short).
    """
    output = os.fspath(output)
    fmt = format_for(output, purpose="write")
    steps = list(fmt.precisions)
    name = quality or fmt.qualities[0]
    views = proof_views(scene)
    with tempfile.TemporaryDirectory(prefix="splatconv-proof-") as folder, \
            progress.stage("proving", len(steps) + (PRUNE_PROOFS if prune else 0), "candidate") as advance:
        c = _Candidates(scene, os.path.join(folder, os.path.basename(output)), views,
                        {"quality": quality, "sort": sort, "zstd_level": zstd_level}, advance)
        if max_bytes is not None:
            fits = [p for p in steps if c.size((p, 0)) <= max_bytes] if c.size((steps[0], 0)) <= max_bytes else []
            if not fits:
                raise OutputError(f"even the coarsest step of the {name!r} setting takes {c.size((steps[0], 0)):,} "
                                  f"bytes, more than --max-bytes {max_bytes:,}", output)
            order = fits[::-1]  # the finest that fits first
        else:
            order = [p for p in steps if p >= 0]
        chosen = next((p for p in order if min_psnr is None or c.proof((p, 0)).worst >= min_psnr), None)
        if chosen is not None and min_psnr is not None and max_bytes is None:
            for p in [q for q in steps if q < chosen][::-1][:MAX_COARSER]:
                if c.proof((p, 0)).worst < min_psnr:
                    break
                chosen = p
        short = None
        if chosen is None:
            chosen = max((key for key in c.proofs), key=lambda key: c.proofs[key].worst)[0]
            short = min_psnr - c.proofs[(chosen, 0)].worst
            if not best_effort:
                b = c.proofs[(chosen, 0)]
                raise OutputError(f"reaches at best {b.worst:.2f} dB in its worst frame ({b.where}, at the "
                                  f"{name!r} setting, precision step {chosen:+d}), below the --min-psnr "
                                  f"{min_psnr:g} dB floor (--best-effort writes it all the same)", output)
        left_out = _pruned(c, chosen, min_psnr) if prune and short is None else 0
        proof = c.proof((chosen, left_out))
        report, pruned = c.put((chosen, left_out))
        # The output is the very file measured, copied into place.
        with open(c.path, "rb") as src, atomic_writer(output, replace=force) as dst:
            shutil.copyfileobj(src, dst, 1 << 20)
    notes = []
    if prune:
        notes.append(pruned.notes[0] if pruned is not None else
                     f"pruned no splat of {len(c.ranked):,} drawable: leaving out the least would break "
                     f"the floor" if short is None else "pruned no splat: the floor is not reached")
    notes.append(f"proved: worst frame {proof.worst:.2f} dB ({proof.where}), mean {proof.mean:.2f} dB, drawn "
                 f"against the scene it encodes from {plural(len(views), 'view')} at t = "
                 f"{', '.join(f'{t:g}' for t in proof.times)}" + (f" (floor {min_psnr:g} dB)" if min_psnr else ""))
    if short is not None:
        notes.append(f"{short:.2f} dB short of the --min-psnr {min_psnr:g} dB floor (--best-effort)")
    return report, notes


def _pruned(c: _Candidates, step: int, min_psnr: float) -> int:
    """How many of the least contributing drawable splats ``step`` can leave out and still reach ``min_psnr``.

    A bisection over the share left out, :data:`PRUNE_PROOFS` proofs at most:
    none left out holds (proved), all cannot (a file holds a splat).
    """
    c.ranked = ranked(c.scene, c.views)
    holds, breaks = 0, len(c.ranked)
    for _ in range(PRUNE_PROOFS):
        if breaks - holds <= max(1, len(c.ranked) // PRUNE_RESOLUTION):
            break
        mid = (holds + breaks) // 2
        if c.proof((step, mid)).worst >= min_psnr:
            holds = mid
        else:
            breaks = mid
    return holds

