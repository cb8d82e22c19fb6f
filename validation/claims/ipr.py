"""Iterative particle reconstruction where particle images crowd (docs/claims.md #55–#57).

On the dense case of :mod:`validation.claims.ipr_scores` (lpt-challenge-small at about
0.05 particles per pixel):

- #55: the OTF the stack measures on the particle images, per camera and depth slab, has
  the width the optics specify (σ = d_τ/4 of :mod:`validation.truth.spot_spec`), within
  the standard error of a median of the fitted isolated images at the claims'
  false-alarm rate;
- #56: iterative particle reconstruction with that OTF, through the true cameras, finds
  at least :data:`MIN_FOUND` of the particles with at most :data:`MAX_GHOSTS` ghosts and
  a projected error of at most :data:`MAX_RMS_PX`, the LPT Challenge's best codes at
  this density (scored as the Challenge scores them, apart from the stack);
- #57: the defocus law (σ² quadratic in depth) fitted to the outer depth slabs' isolated
  images gives the middle slab's σ as specified, within the law's own miss on this rig
  (the same law fitted to the specification) and the standard errors of the fit and of
  a direct measurement of the slab: what the stack fills a slab without images with at
  high density.
"""

import numpy as np
from scipy.stats import norm

from validation.claims.base import Claim, ClaimResult, result
from validation.claims.context import ClaimContext
from validation.claims.image_stack import FALSE_ALARM
from validation.claims.ipr_scores import MEDIAN_EFFICIENCY

#: Fewest particles found, most ghosts and largest projected rms error, px: the best
#: codes of the LPT Challenge at up to 0.05 particles per pixel (the issue's targets).
MIN_FOUND = 0.99
MAX_GHOSTS = 0.01
MAX_RMS_PX = 0.1


def _otf_measured(claim: Claim, ctx: ClaimContext) -> ClaimResult:
    scores = ctx.ipr
    measured = scores.otf_sigma  # (C, S, 2)
    specified = scores.specified_sigma[:, :, None]
    error = MEDIAN_EFFICIENCY * scores.fitted_spread / np.sqrt(scores.otf_counts)
    deviation = (measured - specified) / error[:, :, None]
    k = float(norm.isf(FALSE_ALARM / (2 * deviation.size)))
    worst = float(np.max(np.abs(deviation)))
    ratio = measured / specified
    cameras, slabs = scores.otf_counts.shape
    return result(
        claim,
        worst,
        f"each of {cameras} cameras × {slabs} depth slabs (centres "
        f"{', '.join(f'{z * 1e3:.1f}' for z in scores.slab_centres[0])} mm), σ_x and σ_y of "
        f"the OTF measured on the images ({scores.ppp:.3f} particles per sensor pixel; "
        f"medians of {scores.otf_counts.min()}–{scores.otf_counts.max()} fitted images) "
        f"against the median specified σ = d_τ/4 of the slab's isolated images "
        f"({scores.specified_sigma.min():.3f}–{scores.specified_sigma.max():.3f} px): within "
        f"{k:.2f} SE, SE = {MEDIAN_EFFICIENCY} s/√n of the median of n images, s the spread "
        f"of the σ of {scores.isolated.min()}–{scores.isolated.max()} isolated images fitted "
        f"apart from the stack (SE {np.min(error / scores.specified_sigma):.1%}–"
        f"{np.max(error / scores.specified_sigma):.1%}); measured/specified "
        f"{ratio.min():.4f}–{ratio.max():.4f}, worst {worst:.2f} SE",
        worst <= k,
        limit=k,
    )


def _defocus_law(claim: Claim, ctx: ClaimContext) -> ClaimResult:
    scores = ctx.ipr
    middle = scores.specified_sigma.shape[1] // 2
    specified = scores.specified_sigma[:, middle]
    direct = MEDIAN_EFFICIENCY * scores.fitted_spread[:, middle]
    error = np.hypot(scores.law_se, direct / np.sqrt(scores.isolated[:, middle]))
    model = np.abs(scores.law_model_error)
    off = scores.law_sigma - specified
    beyond = (np.abs(off) - model) / error
    k = float(norm.isf(FALSE_ALARM / (2 * beyond.size)))
    worst = float(np.max(beyond))
    return result(
        claim,
        worst,
        f"each of {beyond.size} cameras: σ of the middle depth slab's isolated images from "
        f"the stack's defocus law (`ptv.reconstruct.defocus_law`, what `synptv run` fills "
        f"a slab without images with) fitted to the outer slabs' images alone (fitted apart "
        f"from the stack), against the slab's median specified σ = d_τ/4 "
        f"({specified.min():.3f}–{specified.max():.3f} px): off by "
        f"{', '.join(f'{v:+.4f}' for v in off)} px, within the law's own miss on this rig "
        f"(the same law fitted to the outer slabs' specified σ: "
        f"{', '.join(f'{v:.4f}' for v in model)} px) and {k:.2f} SE, SE the fit's and a "
        f"direct measurement's of the slab ({error.min():.4f}–{error.max():.4f} px) in "
        f"quadrature; worst {worst:.2f} SE beyond",
        worst <= k,
        limit=k,
    )


def _reconstruction(claim: Claim, ctx: ClaimContext) -> ClaimResult:
    s = ctx.ipr
    margins = (
        (s.found - MIN_FOUND) / (1 - MIN_FOUND),
        (MAX_GHOSTS - s.ghosts) / MAX_GHOSTS,
        (MAX_RMS_PX - s.rms_px) / MAX_RMS_PX,
    )
    return result(
        claim,
        min(margins),
        f"found {s.found:.4f} ≥ {MIN_FOUND} of {s.particles} particles, ghosts {s.ghosts:.4f} ≤ "
        f"{MAX_GHOSTS} of {s.points} points, projected rms {s.rms_px:.4f} ≤ {MAX_RMS_PX} px "
        f"({s.rms_um:.1f} µm in 3-D), points paired one to one with the particles within a "
        f"voxel, {s.ppp:.3f} particles per sensor pixel (the LPT Challenge's best codes at "
        f"0.05 per pixel of the volume's image); value: the smallest fraction of the three "
        f"limits' room left (reconstruction {s.seconds:.1f} s)",
        min(margins) >= 0,
        limit=0.0,
    )


IPR_CLAIMS: tuple[Claim, ...] = (
    Claim(
        "ipr.otf_measured",
        "docs/ptv.md (iterative particle reconstruction: the OTF)",
        "the OTF measured on dense particle images, per camera and depth slab, has the width "
        "the optics specify",
        _otf_measured,
    ),
    Claim(
        "ipr.reconstruction",
        "docs/ptv.md (iterative particle reconstruction)",
        "at 0.05 particles per pixel iterative particle reconstruction finds the particles "
        "as the LPT Challenge's best codes do",
        _reconstruction,
    ),
    Claim(
        "ipr.defocus_law",
        "docs/run.md §12 (IPR: the OTF's depth law)",
        "the defocus law that fills a depth slab without isolated particle images gives "
        "the slab's OTF the width the optics specify",
        _defocus_law,
    ),
)
