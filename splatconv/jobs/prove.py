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
from ..io import read, write
from ..model import Scene
from ..progress import SILENT
from ..render.proof import proof_views, prove
from ..wording import plural
from .convert import convert

#: Coarser steps tried below the first that holds, to spend fewer bytes (each costs a proof).
MAX_COARSER = 2


def check_proof_options(output, min_psnr: float | None, max_bytes: int | None) -> None:
    """Refuse ``--min-psnr`` and ``--max-bytes`` for an output whose format has no precision steps."""
    if min_psnr is None and max_bytes is None:
        return
    if not format_for(output, purpose="write").precisions:
        raise UsageError("--min-psnr and --max-bytes apply to outputs whose format has precision steps "
                         "(.splatvq)", output)
    if min_psnr is not None and not min_psnr > 0:
        raise UsageError(f"--min-psnr must be a positive number of dB, got {min_psnr:g}")
    if max_bytes is not None and max_bytes <= 0:
        raise UsageError(f"--max-bytes must be a positive size, got {max_bytes}")


def convert_proven(source, output, *, min_psnr: float | None, max_bytes: int | None, best_effort: bool = False,
                   **options):
    """:func:`splatconv.jobs.convert.convert` whose output proves its quality (:func:`write_proven`).

    The proof's options are checked before anything is read.
    """
    check_proof_options(output, min_psnr, max_bytes)

    def writer(scene, out, **write_options):
        return write_proven(scene, out, min_psnr=min_psnr, max_bytes=max_bytes, best_effort=best_effort,
                            **write_options)

    return convert(source, output, writer=writer, **options)


def write_proven(scene: Scene, output, *, quality: str | None, min_psnr: float | None, max_bytes: int | None,
                 best_effort: bool = False, sort: str | None = None, zstd_level: int | None = None,
                 force: bool = False, progress=SILENT):
    """Write ``scene`` to ``output`` at the precision step that meets ``min_psnr`` within ``max_bytes``.

    Without ``max_bytes``, steps are tried from the setting as named (0) finer
    until the worst frame reaches ``min_psnr``, then up to :data:`MAX_COARSER`
    coarser while it still does (a frame can be worse at a finer step: the
    viewer's depth sort makes a large splat's small move show). With
    ``max_bytes``, the finest step that fits is tried first, then coarser ones.

    Returns
    -------
    (WriteReport, list of str)
        The candidate's write report and the notes that say what was proved.

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
            progress.stage("proving", len(steps), "candidate") as advance:
        candidate = os.path.join(folder, os.path.basename(output))
        sizes, proofs, on_disk = {}, {}, [None, None]  # on_disk: the step the candidate file holds, its report

        def put(p):
            if on_disk[0] != p:
                on_disk[:] = p, write(scene, candidate, quality=quality, precision=p, sort=sort,
                                      zstd_level=zstd_level, force=True)
                sizes[p] = os.path.getsize(candidate)
            return on_disk[1]

        def size_at(p):
            if p not in sizes:
                put(p)
            return sizes[p]

        def proof_at(p):
            if p not in proofs:
                put(p)
                proofs[p] = prove(scene, read(candidate), views)
                advance()
            return proofs[p]

        if max_bytes is not None:
            fits = [p for p in steps if size_at(p) <= max_bytes] if size_at(steps[0]) <= max_bytes else []
            if not fits:
                raise OutputError(f"even the coarsest step of the {name!r} setting takes {size_at(steps[0]):,} "
                                  f"bytes, more than --max-bytes {max_bytes:,}", output)
            order = fits[::-1]  # the finest that fits first
        else:
            order = [p for p in steps if p >= 0]
        chosen = next((p for p in order if min_psnr is None or proof_at(p).worst >= min_psnr), None)
        if chosen is not None and min_psnr is not None and max_bytes is None:
            for p in [q for q in steps if q < chosen][::-1][:MAX_COARSER]:
                if proof_at(p).worst < min_psnr:
                    break
                chosen = p
        short = None
        if chosen is None:
            chosen = max(proofs, key=lambda p: proofs[p].worst)
            short = min_psnr - proofs[chosen].worst
            if not best_effort:
                b = proofs[chosen]
                raise OutputError(f"reaches at best {b.worst:.2f} dB in its worst frame ({b.where}, at the "
                                  f"{name!r} setting, precision step {chosen:+d}), below the --min-psnr "
                                  f"{min_psnr:g} dB floor (--best-effort writes it all the same)", output)
        proof = proof_at(chosen)
        report = put(chosen)
        # The output is the very file measured, copied into place.
        with open(candidate, "rb") as src, atomic_writer(output, replace=force) as dst:
            shutil.copyfileobj(src, dst, 1 << 20)
    notes = [f"proved: worst frame {proof.worst:.2f} dB ({proof.where}), mean {proof.mean:.2f} dB, drawn against "
             f"the scene it encodes from {plural(len(views), 'view')} at t = "
             f"{', '.join(f'{t:g}' for t in proof.times)}" + (f" (floor {min_psnr:g} dB)" if min_psnr else "")]
    if short is not None:
        notes.append(f"{short:.2f} dB short of the --min-psnr {min_psnr:g} dB floor (--best-effort)")
    return report, notes

