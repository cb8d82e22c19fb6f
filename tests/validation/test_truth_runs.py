"""The detection rung's noise, summed chunk by chunk, against the RMS over the whole run."""

from functools import reduce

import numpy as np
import pytest

from ptv.bins import LogBins
from validation.run.truth_rungs import NoiseSums

BINS = LogBins(1e-4, 2e-2, 6)


def _errors(rng, snapshots, n_dt):
    """errors[k][m] = (particle indices, position errors, ΔX errors, true X(t)), a random
    subset of 40 particles found at each Δt (so the shared-frame intersection has work to
    do)."""
    where = rng.uniform(0, 0.01, (60, 3))
    out = []
    for k in range(n_dt):
        run = {}
        for m in snapshots:
            if k == n_dt - 1 and m % 3 == 0:
                continue  # some snapshots missing at the last Δt
            ids = np.sort(rng.choice(60, size=40, replace=False))
            moves = rng.normal(0, (k + 1) * 1e-5, (40, 3))
            run[m] = (ids, rng.normal(0, 1e-5, (40, 3)), moves, where[ids])
        out.append(run)
    return out


def _reference(errors, shared):
    """The RMS noise written out directly over the whole run."""
    runs = errors
    if shared:
        common_m = set(errors[0])
        for run in errors[1:]:
            common_m &= set(run)
        runs = []
        for run in errors:
            kept = {}
            for m in common_m:
                ids = set(errors[0][m][0])
                for other in errors[1:]:
                    ids &= set(other[m][0])
                mask = np.array([i in ids for i in run[m][0]])
                kept[m] = tuple(a[mask] for a in run[m])
            runs.append(kept)
    position = np.concatenate([v[1] for v in runs[0].values()])
    moves = [np.concatenate([v[2] for v in run.values()]) for run in runs]
    return np.sqrt((position**2).mean(0)), np.array([np.sqrt((d**2).mean(0)) for d in moves])


@pytest.mark.parametrize("shared", [False, True])
def test_noise_summed_over_chunks_is_the_noise_of_the_run(shared):
    rng = np.random.default_rng(4)
    chunks = [range(0, 10), range(10, 20), range(20, 23)]
    per_chunk = [_errors(rng, list(c), 3) for c in chunks]
    whole = [{m: e for part in per_chunk for m, e in part[k].items()} for k in range(3)]
    sums = reduce(NoiseSums.merged, (NoiseSums.of(e, BINS, shared=shared) for e in per_chunk))
    position, displacement = sums.rms()
    ref_position, ref_displacement = _reference(whole, shared)
    np.testing.assert_allclose(position, ref_position, rtol=1e-12)
    np.testing.assert_allclose(displacement, ref_displacement, rtol=1e-12)
    assert displacement.shape == (3, 3)
    whole_pairs = NoiseSums.of(whole, BINS, shared=shared).pairs
    np.testing.assert_allclose(sums.pairs.sum_q, whole_pairs.sum_q, rtol=1e-12)
    np.testing.assert_array_equal(sums.pairs.pairs, whole_pairs.pairs)


def test_no_scored_particle_gives_nan():
    position, displacement = NoiseSums.of([{}, {}], BINS, shared=False).rms()
    assert np.isnan(position).all() and np.isnan(displacement).all()
    assert displacement.shape == (2, 3)
