"""Mutations of the statistics stack (``ptv.stats``), caught by the ``stats`` and ``table3`` claims.

Each probe runs the patched routine on a few synthetic snapshots (40 particles, three Δt),
looked up through its module at call time, as the claims' computation looks it up.
"""

from dataclasses import replace

import numpy as np

from ptv.bins import LogBins
from ptv.stats import dissipation, mean_displacement, multidt, pairs, structure
from ptv.stats.links import RunParticles
from simulator import spectra
from simulator.presets import flow_preset
from validation.mutations.base import Mutation
from validation.mutations.patching import Patch, edited
from validation.mutations.probes import run_statistics_probe

#: The Δt of the probes, s, and their separation bins.
_DT = np.array([1e-3, 2e-3, 3e-3])
_R_RANGE = (1e-3, 5e-2)


def _snapshots() -> list[list[tuple[np.ndarray, np.ndarray]]]:
    """Per Δt, four snapshots of 40 positions (m) and displacements (m)."""
    rng = np.random.default_rng(0)
    return [
        [
            (rng.uniform(0.0, 0.05, (40, 3)), rng.normal(0.0, 1e-4 * (1 + k), (40, 3)))
            for _ in range(4)
        ]
        for k in range(_DT.size)
    ]


def _bins():
    return LogBins(*_R_RANGE, 6)


def _pair_sums():
    x, d = _snapshots()[0][0]
    return pairs.pair_sums(x, d, _bins())


def _snapshot_sums():
    return structure.double_frame_sums(_snapshots(), _bins())


def _line_fit():
    """c₁, c₂ of the bootstrap fit of ⟨q⟩ = 2Δt² + 3e-6 with replicates scattered by 1 %."""
    rng = np.random.default_rng(1)
    y = np.array([2.0 * _DT**2 + 3e-6])
    replicates = y * (1 + 0.01 * rng.standard_normal((50, *y.shape)))
    fit = multidt.fit_multi_dt_bootstrap(_DT, y, replicates)
    return np.concatenate([fit.c1, fit.c2])


def _structure_function(field: str = "s2"):
    return getattr(structure.structure_function(_snapshot_sums(), _DT, n_boot=20, rng=2), field)


def _mean_displacement():
    runs = [
        RunParticles.from_links(k, dt, run)
        for k, (dt, run) in enumerate(zip(_DT, _snapshots(), strict=True))
    ]
    return mean_displacement.mean_displacement(runs).se


def _epsilon():
    return dissipation.epsilon_estimate(np.array([1e-3]), np.array([5e-3]))


def _plateau():
    r = np.geomspace(2e-3, 2e-2, 5)
    profile = dissipation.dissipation_profile(r, 2.0 * (0.1 * r) ** (2 / 3) * (1 + r / 0.1))
    return dissipation.plateau_epsilon(profile, r_min=2e-3, r_max=2e-2, method="max").epsilon


def _spectrum():
    spectrum = spectra.PopeSpectrum(flow_preset("lem-10hz").parameters)
    return spectrum.energy(np.geomspace(spectrum.k_min, spectrum.k_max, 5))


def _scales():
    s = dissipation.turbulence_scales(0.19, 0.1, nu=1e-6)
    return np.array([s.eta, s.tau_eta, s.re_lambda])


def _biased_pair_sums(factor: float):
    """A ``pair_sums`` whose Σq is ``factor`` times the true one (Σq² factor² times)."""

    def make(original):
        def pair_sums(positions, increments, bins):
            sums = original(positions, increments, bins)
            return replace(sums, sum_q=factor * sums.sum_q, sum_q2=factor**2 * sums.sum_q2)

        return pair_sums

    return make


STATISTICS_MUTATIONS: tuple[Mutation, ...] = (
    Mutation(
        "c2-1.5-in-estimator",
        "ε = (S2/C₂)^{3/2}/r divides by 1.5 instead of the C₂ it is given (2)",
        (
            Patch(
                "ptv.stats.dissipation:epsilon_estimate",
                edited("(pos / kolmogorov_c2) ** 1.5", "(pos / 1.5) ** 1.5"),
            ),
        ),
        ("stats.epsilon_recovered", "stats.epsilon_convention"),
        ("stats",),
        _epsilon,
    ),
    Mutation(
        "pair-sums-3pc-high",
        "the shared pair-sum kernel returns Σq 3 % high (every binned ⟨q⟩ and the stack's "
        "own sample truth alike)",
        (Patch("ptv.stats.pairs:pair_sums", _biased_pair_sums(1.03)),),
        (
            "stats.c1_matches_truth",
            "stats.correlated_noise_removed",
            "stats.raw_s2_biased",
            "stats.epsilon_recovered",
        ),
        ("stats",),
        lambda: _pair_sums().sum_q,
    ),
    Mutation(
        "r-bin-off-by-one",
        "the pair kernel puts each pair one separation bin further out (the last bin keeps "
        "its own)",
        (
            Patch(
                "ptv.stats.pairs:_start_chunks",
                edited(
                    "int((log(r) - log_r_min) * inv_dlog)",
                    "int((log(r) - log_r_min) * inv_dlog) + 1",
                ),
            ),
        ),
        ("stats.c1_matches_truth", "stats.correlated_noise_removed", "stats.raw_s2_biased"),
        ("stats",),
        lambda: _pair_sums().count,
    ),
    Mutation(
        "fit-without-intercept",
        "the multi-Δt fit drops the intercept c₂: ⟨q⟩ = c₁Δt² through the origin",
        (
            Patch(
                "ptv.stats.multidt:fit_multi_dt_bootstrap",
                edited(
                    "a, _ = _wls_operator(x, w)",
                    "a, _ = _wls_operator(x, w)\n"
                    "        a = np.stack([w * x / (w * x * x).sum(axis=1)[:, None], 0 * w], 1)",
                ),
            ),
        ),
        ("stats.c1_matches_truth", "stats.c2_positive", "stats.linear_in_dt2"),
        ("stats",),
        _line_fit,
    ),
    Mutation(
        "fit-in-dt-not-dt2",
        "the multi-Δt fit takes Δt instead of Δt² as its abscissa",
        (
            Patch(
                "ptv.stats.multidt:fit_multi_dt_bootstrap",
                edited(
                    "x = np.broadcast_to(dt[idx] ** 2, ys.shape)",
                    "x = np.broadcast_to(dt[idx], ys.shape)",
                ),
            ),
        ),
        ("stats.c1_matches_truth", "stats.linear_in_dt2", "stats.epsilon_recovered"),
        ("stats",),
        _line_fit,
    ),
    Mutation(
        "dt-off-by-one",
        "the structure function fits column k of ⟨q⟩ at Δt_{k+1} (the last column at its own Δt)",
        (
            Patch(
                "ptv.stats.structure:structure_function",
                edited(
                    "dt = np.asarray(dt, dtype=np.float64)\n",
                    "dt = np.asarray(dt, dtype=np.float64)\n"
                    "    dt = dt[np.minimum(np.arange(dt.size) + 1, dt.size - 1)]\n",
                ),
            ),
        ),
        ("stats.c1_matches_truth", "stats.epsilon_recovered"),
        ("stats",),
        _structure_function,
    ),
    Mutation(
        "raw-s2-over-dt",
        "the raw (single-Δt) S2 is ⟨q⟩/Δt instead of ⟨q⟩/Δt²",
        (
            Patch(
                "ptv.stats.structure:structure_function",
                edited("raw_s2=y / dt2,", "raw_s2=y / dt,"),
            ),
        ),
        ("stats.raw_s2_biased", "stats.noisy_estimates_higher"),
        ("stats",),
        lambda: _structure_function("raw_s2"),
    ),
    Mutation(
        "bootstrap-too-narrow",
        "the bootstrap draws four times as many snapshots as each run holds (σ of every "
        "⟨q⟩ halved, as when correlated pairs are resampled as if independent)",
        (
            Patch(
                "ptv.stats.snapshots:SnapshotSums.bootstrap_weights",
                edited("gen.multinomial(members.size, p", "gen.multinomial(4 * members.size, p"),
            ),
        ),
        # Not #8: a halved σ shows there only where c1's honest deviation exceeds half its
        # tolerance (docs/claims.md §5).
        ("stats.raw_s2_biased",),
        ("stats",),
        lambda: _snapshot_sums().bootstrap_weights(5, rng=0),
    ),
    Mutation(
        "mean-displacement-se-not-divided",
        "the mean displacement's error is the scatter of the snapshot means, not its "
        "standard error (√M too large): the frame-offset test goes blind",
        (
            Patch(
                "ptv.stats.mean_displacement:mean_displacement",
                edited(
                    "mean[i], se[i] = cluster_mean(n, np.array([p.mean(axis=0) for p in per]))",
                    "mean[i], se[i] = cluster_mean(n, np.array([p.mean(axis=0) for p in per]))\n"
                    "            se[i] *= np.sqrt(len(per))",
                ),
            ),
        ),
        ("stats.mean_linear_in_dt",),
        ("stats",),
        _mean_displacement,
    ),
    Mutation(
        "plateau-always-mean",
        "the ε plateau is the mean of ε(r) over the range even when its maximum is asked for",
        (
            Patch(
                "ptv.stats.dissipation:plateau_epsilon",
                edited('if method == "mean":', "if True:"),
            ),
        ),
        ("stats.epsilon_recovered",),
        ("stats",),
        _plateau,
    ),
    Mutation(
        "run-plateau-over-every-bin",
        "synptv run's plateau ε averages ε(r) over every bin, not over the plateau range",
        (
            Patch(
                "ptv.stats.run_statistics:_plateau",
                edited(
                    "r_min=settings.plateau[0],\n            r_max=settings.plateau[1],",
                    "r_min=settings.r_min,\n            r_max=settings.r_max,",
                ),
            ),
        ),
        ("run.epsilon",),
        ("run",),
        lambda: run_statistics_probe().plateau.epsilon,
    ),
    Mutation(
        "u-prime-noise-kept",
        "the Eulerian variance fit reports the raw variance at the largest Δt over Δt², the "
        "noise 2σ_b²/Δt² left in u′",
        (
            Patch(
                "ptv.stats.eulerian:eulerian_fit",
                edited(
                    '("variance", vfit.c1),',
                    '("variance", vfit.c1 + vfit.c2 / dt[idx].max() ** 2),',
                ),
            ),
        ),
        ("run.u_prime",),
        ("run",),
        lambda: run_statistics_probe().u_prime.value,
    ),
    Mutation(
        "kolmogorov-constant-1.3",
        "the simulator's Pope spectrum takes C_K = 1.3 instead of 1.5 (c_L, c_η re-solved, "
        "so u′ and ε still hold; the exact D_LL and the ε deficit move with the flow)",
        (
            Patch(
                "simulator.spectra:PopeSpectrum._shape",
                edited("return self.C * p.epsilon", "return 1.3 * p.epsilon"),
            ),
        ),
        ("flow.pope_spectrum",),
        ("flow", "stats"),
        _spectrum,
    ),
    Mutation(
        "taylor-factor-10",
        "the Taylor microscale as √(10νu′²/ε) instead of √(15νu′²/ε) (R_λ 18 % low)",
        (
            Patch(
                "ptv.stats.dissipation:turbulence_scales",
                edited(
                    "np.sqrt(15.0 * nu * u_prime**2 / epsilon)",
                    "np.sqrt(10.0 * nu * u_prime**2 / epsilon)",
                ),
            ),
        ),
        ("table3.arithmetic",),
        ("table3",),
        _scales,
    ),
)
