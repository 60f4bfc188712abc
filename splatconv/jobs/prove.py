"""``convert`` to a compressed output that proves its quality: candidates at each precision step, measured,
the one that holds written.

``convert OUT.splatvq`` proves the file it writes reaches its setting's floor
(:attr:`splatconv.formats.base.Format.floors`: 45 dB default, 40 small), or the
floor ``--min-psnr`` sets; ``--max-bytes SIZE`` asks for a size instead;
``--no-proof`` writes the setting as named, unmeasured. Each candidate is
written in full to a temporary folder, read back as any reader would, and drawn
against the scene it encodes (:mod:`splatconv.render.proof`, whose source
frames are drawn once); the output is then the very bytes that were measured.
"""

from __future__ import annotations

import math
import os
import shutil
import tempfile
import time

import numpy as np

from ..errors import OutputError, UsageError
from ..files.output import atomic_writer
from ..files.heap import trim
from ..files.paging import hand_back
from ..io import check_write_options, write
from ..model import Scene
from ..progress import SILENT
from ..ops.prune import leave_out
from ..publish import PAGE
from ..render.proof import PROOF_TIMES, Prover, frame_weights, proof_plan, proof_views, ranked
from ..viewer import DRAWABLE, undrawable_kinds
from ..wording import plural
from .convert import PROVE_MEMORY_BYTES, convert

#: Candidates tried coarser than the first that holds, to spend fewer bytes (each costs a proof).
MAX_COARSER = 3
#: About what a half step buys or costs in the worst frame: the search jumps by the dB it lacks or has.
#: Measured from the setting to two steps finer: 1.3 dB a half step on a real scene of few large
#: splats, 1.45 on the bench's 1M-splat scene (3 dB had it climb a half step at a time there).
DB_PER_HALF_STEP = 1.5
#: Candidates ``--prune`` proves at most, and the share of the drawable splats it stops at (1/128).
PRUNE_PROOFS = 7
PRUNE_RESOLUTION = 128
#: Tuning (:func:`_tuned`): notches it keeps at most (each a full proof), and the scenes it is tried
#: on (drawable splats: what a proof draws), where a proof is quick.
TUNE_NOTCHES = 16
TUNE_MAX_SPLATS = 100_000
#: Past this many drawable splats a tuning keeps at most :data:`TUNE_NOTCHES_LARGE` notches: each a proof
#: of some seconds, for bytes that are a smaller share of the file than a small scene's.
TUNE_MANY_SPLATS = 50_000
TUNE_NOTCHES_LARGE = 8


def _precisions(output) -> tuple:
    """The precision steps of ``output``'s format (none for a page or a format without them)."""
    try:
        return check_write_options(output, also=(PAGE,)).precisions
    except UsageError:
        return ()


def check_proof_options(output, min_psnr: float | None, max_bytes: int | None, prune: bool = False,
                        proof: bool = True, best_effort: bool = False) -> bool:
    """Refuse proof options that mean nothing for ``output`` or together; whether ``output`` is proved.

    A format with precision steps is proved unless ``proof`` is False (``--no-proof``).
    """
    asked = min_psnr is not None or max_bytes is not None
    if not proof and (asked or prune or best_effort):
        raise UsageError("--no-proof writes the setting unmeasured: no --min-psnr, --max-bytes, --best-effort "
                         "or --prune with it")
    if min_psnr is not None and not min_psnr > 0:
        raise UsageError(f"--min-psnr must be a positive number of dB, got {min_psnr:g}")
    if max_bytes is not None and max_bytes <= 0:
        raise UsageError(f"--max-bytes must be a positive size, got {max_bytes}")
    if prune and min_psnr is None and max_bytes is not None:
        raise UsageError("--prune leaves out splats while a floor holds: with --max-bytes, give --min-psnr")
    if best_effort and min_psnr is None and max_bytes is not None:
        raise UsageError("--best-effort goes with a floor: with --max-bytes, give --min-psnr")
    if not _precisions(output):
        if asked or prune or best_effort:
            raise UsageError("--min-psnr, --max-bytes, --best-effort and --prune apply to outputs whose format "
                             "has precision steps (.splatvq)", output)
        return False
    return proof


def convert_proven(source, output, *, min_psnr: float | None = None, max_bytes: int | None = None,
                   best_effort: bool = False, prune: bool = False, proof: bool = True, **options):
    """:func:`splatconv.jobs.convert.convert`, whose output proves its quality (:func:`write_proven`) when its
    format has precision steps and ``proof`` holds.

    The proof's options are checked before anything is read.
    """
    if not check_proof_options(output, min_psnr, max_bytes, prune, proof, best_effort):
        return convert(source, output, **options)

    def writer(scene, out, **write_options):
        return write_proven(scene, out, min_psnr=min_psnr, max_bytes=max_bytes, best_effort=best_effort,
                            prune=prune, **write_options)

    return convert(source, output, writer=writer, memory=PROVE_MEMORY_BYTES, **options)


class _Candidates:
    """Candidate files of one output, each written once to a temporary folder and measured once.

    A candidate is a precision step, the quantizers tuned a notch coarser beyond
    it (:attr:`~splatconv.formats.base.Format.tunings`, a name once a notch) and a
    number of splats left out: the first that many of ``ranked`` (drawable rows,
    least contributing first).
    """

    def __init__(self, scene: Scene, path: str, prover: Prover, options: dict, advance, prepare=None,
                 prepared=None, weights=None):
        self.scene, self.path, self.prover, self.options, self.advance = scene, path, prover, options, advance
        # What each splat adds to the proof's frames, for a format that spends its bits by it (Format.weighs).
        self.weights = weights
        # The format's prepare() and what it gave for the scene: what every unpruned candidate shares.
        self.prepare, self.prepared = prepare, prepared
        self.pruned_last = None  # (left out, the pruned scene, its pruning report, its prepare()): its candidates'
        self.ranked = None
        self.sizes, self.proofs = {}, {}
        self.on_disk = None, None, None  # the candidate the file holds, its write report, its pruning report

    def put(self, key) -> tuple:
        """Write candidate ``key`` (step, tuning, left out) unless the file holds it: its write and pruning
        reports."""
        if self.on_disk[0] != key:
            step, tune, left_out = key
            scene, pruned, prepared, weights = self.scene, None, self.prepared, self.weights
            if left_out:
                if self.pruned_last is None or self.pruned_last[0] != left_out:
                    scene, pruned = leave_out(self.scene, self.ranked[:left_out], of=len(self.ranked))
                    kept = None if self.weights is None else np.delete(self.weights, self.ranked[:left_out])
                    self.pruned_last = left_out, scene, pruned, self.prepare(scene) if self.prepare else None, kept
                _, scene, pruned, prepared, weights = self.pruned_last
            trim()  # what the last candidate's decode and draws freed, given back before this write
            self.on_disk = key, write(scene, self.path, precision=step, tune=tune, force=True, prepared=prepared,
                                      weights=weights, **self.options), pruned
            # A mapped input's pages, read again by the next write: none held beside the decode and draws.
            hand_back(self.scene.columns.values())
            trim()
            self.sizes[key] = os.path.getsize(self.path)
        return self.on_disk[1:]

    def size(self, key) -> int:
        if key not in self.sizes:
            self.put(key)
        return self.sizes[key]

    def proof(self, key):
        """Candidate ``key``'s proof, every frame drawn."""
        if key not in self.proofs or not self.proofs[key].complete:
            self.put(key)
            self.proofs[key] = self.prover.prove(self.path)
            self.advance()
        return self.proofs[key]

    def holds(self, key, floor: float, like) -> bool:
        """Whether candidate ``key`` reaches ``floor``: drawn until a frame falls below it, the worst frames
        of candidate ``like`` (proved) first, where a coarser candidate fails soonest. A candidate that holds
        is proved in full; one that fails is known to from the frame that broke the floor."""
        if key not in self.proofs:
            self.put(key)
            first = np.argsort(np.asarray(self.proof(like).values), kind="stable")
            self.proofs[key] = self.prover.prove(self.path, floor=floor, first=first)
            self.advance()
        return self.proofs[key].worst >= floor


def write_proven(scene: Scene, output, *, quality: str | None, min_psnr: float | None = None,
                 max_bytes: int | None = None, best_effort: bool = False, prune: bool = False,
                 sort: str | None = None, zstd_level: int | None = None, force: bool = False, progress=SILENT):
    """Write ``scene`` to ``output`` at the precision step that meets a floor within ``max_bytes``.

    The floor is ``min_psnr``, else the setting's (``Format.floors``) unless
    ``max_bytes`` is given (then the finest step that fits, whatever it reaches).
    Without ``max_bytes``, the setting as named (step 0) is proved first; while
    the worst frame reaches the floor, up to :data:`MAX_COARSER` half steps
    coarser are tried (a frame can be worse at a finer step: the viewer's depth
    sort makes a large splat's small move show), else finer ones until one
    does. With ``max_bytes``, the finest step that fits is tried first, then
    coarser ones.

    With ``prune``, at the step chosen so, the drawable splats that add least
    to the proof's frames (:func:`splatconv.render.proof.ranked`) are left out,
    as many as a bisection of :data:`PRUNE_PROOFS` candidates finds while the
    worst frame still reaches the floor.

    A setting below the best (``small``) whose step climbed past 0 on a tuned
    scene also finds the best setting's file (:func:`_other_family`), and writes
    it where it is smaller.

    Returns
    -------
    (WriteReport, list of str)
        The candidate's write report and the notes that say what was pruned and proved.

    Raises
    ------
    OutputError
        Nothing fits ``max_bytes``, or no step reaches the floor (unless
        ``best_effort``, which writes the best measured and says how far short).
    """
    output = os.fspath(output)
    fmt = check_write_options(output, quality=quality)
    steps = list(fmt.precisions)
    name = quality or fmt.qualities[0]
    floor = min_psnr if min_psnr is not None else fmt.floors.get(name) if max_bytes is None else None
    whose = f"--min-psnr {floor:g} dB floor" if min_psnr is not None else f"{floor:g} dB floor of the {name!r} setting" \
        if floor is not None else ""
    started = time.perf_counter()
    # What every candidate's write shares, computed once (and before the renderer holds its memory).
    kinds = undrawable_kinds(scene.columns)
    drawable = kinds == DRAWABLE
    prepared = fmt.prepare(scene, kinds) if fmt.prepare is not None else None
    shown = int(np.count_nonzero(drawable))  # what a proof draws
    tunes = floor is not None and bool(fmt.tunings) and shown <= TUNE_MAX_SPLATS
    notches = TUNE_NOTCHES if shown <= TUNE_MANY_SPLATS else TUNE_NOTCHES_LARGE
    # A setting below the best must not write a larger file than the best's: where a scene is tuned
    # and the setting's ladder climbed past it (the ladders part ways), the best setting's file is
    # found too (_other_family).
    other = fmt.qualities[0] if tunes and not prune and max_bytes is None and name != fmt.qualities[0] else None
    every = proof_views(scene, drawable)
    views, times = proof_plan(scene, every)
    large = len(views) < len(every) or len(times) < len(PROOF_TIMES)
    # What each splat adds to the proof's frames: the format spends its bits by it, and pruning leaves
    # out the least. Before the renderer holds its memory; a mapped input's pages handed back after.
    weights = frame_weights(scene, views, times, drawable) if fmt.weighs or prune else None
    hand_back(scene.columns.values())
    with tempfile.TemporaryDirectory(prefix="splatconv-proof-") as folder, \
            progress.stage("proving", len(steps) + (PRUNE_PROOFS if prune else 0)
                           + (notches + len(fmt.tunings) if tunes else 0) * (2 if other else 1)
                           + (len(steps) if other else 0),
                           "candidate") as advance, \
            Prover(scene, views, times) as prover:
        options = {"quality": quality, "sort": sort, "zstd_level": zstd_level}
        c = _Candidates(scene, os.path.join(folder, os.path.basename(output)), prover, options, advance,
                        fmt.prepare, prepared, weights if fmt.weighs else None)
        if max_bytes is not None:
            coarsest = c.size((steps[0], (), 0))
            fits = [p for p in steps if c.size((p, (), 0)) <= max_bytes] if coarsest <= max_bytes else []
            if not fits:
                raise OutputError(f"even the coarsest step of the {name!r} setting takes {coarsest:,} "
                                  f"bytes, more than --max-bytes {max_bytes:,}", output)
            order = fits[::-1]  # the finest that fits first
            chosen = next((p for p in order if floor is None or c.proof((p, (), 0)).worst >= floor), None)
        else:
            chosen = _searched(c, steps, floor, large=large)
        short, tune = None, ()
        if chosen is None:
            chosen = max((key for key in c.proofs), key=lambda key: c.proofs[key].worst)[0]
            short = floor - c.proofs[(chosen, (), 0)].worst
            if not best_effort:
                b = c.proofs[(chosen, (), 0)]
                raise OutputError(f"reaches at best {b.worst:.2f} dB in its worst frame ({b.where}, at "
                                  f"{precision_text(name, chosen)}), below the {whose} (--best-effort writes it "
                                  "all the same)", output)
        # Pruning first: leaving out a splat saves more bytes for the dB it costs than any notch.
        left_out = _pruned(c, chosen, floor, views, times, weights, drawable) if prune and short is None else 0
        if tunes and short is None:
            tune = _tuned(c, fmt.tunings, chosen, left_out, floor, notches)
        tried, family, instead = 0, name, None
        if other and short is None and chosen > 0:
            o = _Candidates(scene, os.path.join(folder, "other-" + os.path.basename(output)), prover,
                            dict(options, quality=other), advance, fmt.prepare, prepared, c.weights)
            found = _other_family(o, steps, fmt.tunings, fmt.floors.get(other, floor) if min_psnr is None else floor,
                                  large, notches)
            if found is not None and o.size(found) < c.size((chosen, tune, left_out)):
                instead = f"smaller than the {name!r} setting's best, {c.size((chosen, tune, left_out)):,} bytes"
                tried, family, c, (chosen, tune, _) = len(c.proofs), other, o, found
            else:
                tried = len(o.proofs)
        proof = c.proof((chosen, tune, left_out))
        report, pruned = c.put((chosen, tune, left_out))
        # The output is the very file measured, copied into place.
        with open(c.path, "rb") as src, atomic_writer(output, replace=force) as dst:
            shutil.copyfileobj(src, dst, 1 << 20)
        tried += len(c.proofs)
    notes = []
    if prune:
        notes.append(pruned.notes[0] if pruned is not None else
                     f"pruned no splat of {len(c.ranked):,} drawable: leaving out the least would break "
                     f"the floor" if short is None else "pruned no splat: the floor is not reached")
    drawn = f"{plural(len(views), 'view')} at t = {', '.join(f'{t:g}' for t in proof.times)}"
    if len(views) < len(every) or len(times) < len(PROOF_TIMES):
        drawn += f" (of {len(every)} views: a scene of {scene.count:,} splats is proved from fewer frames)"
    worst = f"worst frame {proof.worst:.2f} dB ({proof.where}), mean {proof.mean:.2f} dB" \
        if proof.worst < float("inf") else "every frame identical to its source's"
    notes.append(f"proved: {worst}, drawn "
                 f"against the scene it encodes from {drawn}, at {precision_text(family, chosen)}"
                 + (f", tuned to the scene ({tuning_text(tune)})" if tune else "")
                 + (f" ({instead})" if instead else "")
                 + (f" (floor {floor:g} dB)" if floor is not None else "")
                 + f"; {plural(tried, 'candidate')} in {time.perf_counter() - started:.1f} s")
    if short is not None:
        notes.append(f"{short:.2f} dB short of the {whose} (--best-effort)")
    return report, notes


def _searched(c: _Candidates, steps: list, floor: float, large: bool = False) -> int | None:
    """The coarsest step found to reach ``floor``, or None: the setting (step 0) first, then finer by the
    half steps the dB it lacks ask for (:data:`DB_PER_HALF_STEP`, at least one), until a step holds; then
    coarser by the dB it has to spare, at most :data:`MAX_COARSER` proofs, halving the gap to the finest
    step proved short instead where the jump would reach it. On a ``large`` scene (proved from fewer
    frames, each proof some ten seconds a million splats), never to the step between the one chosen and
    one proved short where the mean of the two falls short (:func:`_short_between`)."""
    last = steps[-1]
    p = 0
    while True:
        worst = c.proof((p, (), 0)).worst
        if worst >= floor:
            break
        if p >= last:
            return None
        p = min(last, p + max(1, int(math.ceil((floor - worst) / DB_PER_HALF_STEP))))
    chosen = p
    # The finest step proved short of the floor below the chosen one (or one past the coarsest).
    low = max((k[0] for k, b in c.proofs.items() if k[1:] == ((), 0) and k[0] < chosen and b.worst < floor),
              default=steps[0] - 1)
    for _ in range(MAX_COARSER):
        spare = min(c.proof((chosen, (), 0)).worst - floor, 100.0)  # identical frames: inf
        q = max(steps[0], chosen - max(1, int(spare // DB_PER_HALF_STEP)))
        if q <= low:
            q = (low + chosen) // 2  # the jump reaches a step known short: halve the gap instead
        if q <= low or q >= chosen:
            break
        if large and _short_between(c, q, chosen, floor):
            break
        if c.proof((q, (), 0)).worst >= floor:
            chosen = q
        else:
            low = q
    return chosen


def _short_between(c: _Candidates, q: int, chosen: int, floor: float) -> bool:
    """Whether step ``q`` is the one half step between ``chosen`` and a step proved short of ``floor``, and
    the mean of their worst frames falls short of it too: a proof of ``q`` would most likely fail (on the
    bench's 1M-splat scene: 43.08 and 45.98 dB about 43.67), and on a large scene a proof is a third of
    the time. A guess all the same: the dB a step buys is uneven (a real scene of 477 splats: 30.1 dB at
    the setting, 42.0 two half steps finer, 44.4 three, 46.6 seven), so only a large scene takes it."""
    low = q - 1
    if chosen != q + 1 or (low, (), 0) not in c.proofs:
        return False
    w_low, w_top = c.proofs[(low, (), 0)].worst, c.proofs[(chosen, (), 0)].worst
    return w_low < floor and math.isfinite(w_top) and (w_low + w_top) / 2 < floor


def precision_text(name: str, step: int) -> str:
    """``"the 'default' setting"`` or ``"the 'default' setting, 1.5 steps finer"``."""
    if not step:
        return f"the {name!r} setting"
    return f"the {name!r} setting, {abs(step) / 2:g} {'step' if abs(step) == 2 else 'steps'} " \
           f"{'finer' if step > 0 else 'coarser'}"


def _tuned(c: _Candidates, tunings: tuple, step: int, left_out: int, floor: float,
           notches: int = TUNE_NOTCHES) -> tuple:
    """The quantizers ``step`` (with ``left_out`` splats pruned) can take a notch coarser each and still reach
    ``floor``: a tuning to the scene.

    The setting's numbers were chosen over many scenes; a scene often has
    precision to spare in some quantizers (few moving splats, temporal centres on
    a coarse grid, faint splats). In the order of ``tunings`` (the format's, those
    that cost least for the bytes they save on real scenes first), each quantizer
    is taken a notch coarser where that makes the file smaller and the candidate
    still reaches the floor; one that breaks it is not tried again. Pass after
    pass, at most ``notches`` kept (:data:`TUNE_NOTCHES`; :data:`TUNE_NOTCHES_LARGE` on a scene of
    more than :data:`TUNE_MANY_SPLATS` drawable splats). A notch is kept only on a proof of
    every frame: a proof from fewer frames misleads, since a notch can move the
    viewer's depth sort and spoil a frame that was among the best (on a real scene,
    one position notch took a view from 51 dB to 44.5 while its worst frame held).
    A notch that breaks the floor is known to from the first frame below it
    (:meth:`_Candidates.holds`), so a failed notch costs a frame or two and is not
    counted: each quantizer fails once at most.
    """
    tune, left, kept = (), list(tunings), 0
    while left and kept < notches:
        for name in list(left):
            if kept >= notches:
                break
            key = (step, tune + (name,), left_out)
            if c.size(key) >= c.size((step, tune, left_out)):  # at its limit, or nothing to gain
                left.remove(name)
                continue
            if c.holds(key, floor, like=(step, tune, left_out)):
                tune = key[1]
                kept += 1
            else:
                left.remove(name)
    return tune


def _other_family(c: _Candidates, steps: list, tunings: tuple, floor: float, large: bool,
                  notches: int = TUNE_NOTCHES):
    """The candidate the best setting (``c``'s quality) is written at for its ``floor``, tuned, as ``convert``
    of that setting finds it; None where none of its steps reaches the floor.

    A lower setting has its quantizers coarser than the best's, yet is not always a
    smaller file at its lower floor: where its own ladder must climb past a step
    that breaks the floor (the depth sort makes the dB a step buys uneven), and the
    two tunings go their own ways, the best setting's file can come out smaller (the
    suite's generated 900-splat scene: 17,000 bytes at the default setting's 45 dB,
    17,156 at the small one's 40). ``convert --quality small`` then writes the
    default setting's file, which is above both floors. It is looked for only where
    the lower setting's ladder climbed past its setting (a proof of that setting fell
    short): a lower setting held at its own step or coarser is that many steps
    coarser than the best's, and on a typical real scene (``yellow_clip3``) the best's
    search and tuning would take the run from 33 s to 56 s.
    """
    chosen = _searched(c, steps, floor, large=large)
    if chosen is None:
        return None
    return chosen, _tuned(c, tunings, chosen, 0, floor, notches), 0


def tuning_text(tune) -> str:
    """``"time_shift 2 notches coarser, rotation_bits 1 notch coarser"``: how many notches each quantizer of
    ``tune`` was coarsened, in the order first tried."""
    counts = {}
    for name in tune:
        counts[name] = counts.get(name, 0) + 1
    return ", ".join(f"{name} {n} {'notch' if n == 1 else 'notches'} coarser" for name, n in counts.items())


def _pruned(c: _Candidates, step: int, floor: float, views: list, times, weights, drawable) -> int:
    """How many of the least contributing drawable splats ``step`` can leave out and still reach ``floor``.

    A bisection over the share left out, :data:`PRUNE_PROOFS` proofs at most:
    none left out holds (proved), all cannot (a file holds a splat).
    """
    c.ranked = ranked(c.scene, views, times, weights, drawable)
    holds, breaks = 0, len(c.ranked)
    for _ in range(PRUNE_PROOFS):
        if breaks - holds <= max(1, len(c.ranked) // PRUNE_RESOLUTION):
            break
        mid = (holds + breaks) // 2
        if c.holds((step, (), mid), floor, like=(step, (), holds)):
            holds = mid
        else:
            breaks = mid
    return holds
