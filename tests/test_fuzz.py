"""A short fuzz campaign: mutated files never crash, hang, warn or leave files behind.

The mutants (bit flips, truncations, header edits, huge counts, deep nesting, big
numbers, zstd bombs; see :mod:`tests.fuzzing`) come from a fixed seed, so a
failure is reproducible; the failing file is kept in the test's folder. The long
campaign is ``bench/bench_fuzz.py``.
"""

from __future__ import annotations

from collections import Counter

from .fuzzing import campaign

#: Mutants in CI: every mutator and seed several times over, in well under a minute.
CI_MUTANTS = 160
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
    assert sum(o.name.startswith("scene.splatvq") for o in outcomes) >= 20
    assert any(o.kind.startswith("zstd bomb") for o in outcomes)
