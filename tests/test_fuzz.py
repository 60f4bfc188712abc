"""A short fuzz campaign: mutated files never crash, hang, warn or leave files behind.

The mutants (bit flips, truncations, header edits, huge counts, deep nesting, big
numbers, zstd bombs; see :mod:`tests.fuzzing`) come from a fixed seed, so a
failure is reproducible; the failing file is kept in the test's folder. The long
campaign is ``bench/bench_fuzz.py``.
"""

from __future__ import annotations

from collections import Counter

from .fuzzing import MUTATORS, STATIC_SEEDS, campaign

#: Mutants in CI: every mutator and every seed file (each format, compressed or not) at least twice, and a zstd
#: bomb, in a few seconds; the long campaign (``bench/bench_fuzz.py``, 2,000 by default) is where numbers tell.
CI_MUTANTS = 42
CI_SEED = 20261123


def test_fuzz_campaign(tmp_path):
    outcomes = campaign(tmp_path, CI_SEED, CI_MUTANTS)
    failures = [f"#{o.index} {o.name} [{o.kind}]: {'; '.join(o.problems)}" for o in outcomes if o.problems]
    assert failures == []
    # The campaign is worth its time only if it reaches both outcomes and every mutator.
    codes = Counter(code for o in outcomes for code in o.exit_codes)
    assert codes[0] > 50 and codes[1] > 200
    kinds = Counter(k for o in outcomes for k in o.kind.split("+"))
    assert {"bit_flips", "byte_values", "truncate", "extend", "header_edit", "huge_count", "splatvq_payload"} <= set(kinds)
    assert set(MUTATORS) <= set(kinds)
    seeds = Counter(o.name for o in outcomes)
    names = {p.name for p in (tmp_path / "seeds").iterdir()}  # the campaign's seed files (fuzzing.make_seeds)
    assert {"scene.splatvq", "scene.splatvq.zst", "scene.splatv", "scene.splat", "lite.ply", *STATIC_SEEDS} <= names
    assert set(seeds) == names and min(seeds.values()) >= 2, seeds
    assert any(o.kind.startswith("zstd bomb") for o in outcomes)
