"""The run report's linking table: per linked rung and Δt, the matching tolerance, the
link speed and radius, the particle spacing and the ambiguity of the links."""

from ptv.pipeline.double_frame import AMBIGUITY_WARNING
from validation.report.html_parts import percent, table

__all__ = ["linking_table"]


def linking_table(results: dict) -> list[str]:
    """Per linked rung and Δt: the matching tolerance, the link radius, the particle
    spacing and the ambiguity."""
    rows = []
    for variant, entry in results["ptv"].items():
        summary = entry["summary"]
        speed = summary.get("link_speed")
        source = "given" if speed is None else "measured"
        tolerance = summary["settings"]["tolerance"]
        tolerance_source = "given" if summary.get("match_tolerance") is None else "measured"
        for c in summary["counts"]:
            if c["link_radius"] is None:
                continue
            rows.append(
                (
                    variant,
                    f"{c['dt'] * 1e3:.4g}",
                    "–" if tolerance is None else f"{tolerance * 1e6:.3g} ({tolerance_source})",
                    f"{summary['settings']['max_speed']:.3g} ({source})",
                    f"{c['link_radius'] * 1e3:.3g}",
                    "–" if c["particle_spacing"] is None else f"{c['particle_spacing'] * 1e3:.3g}",
                    percent(c["ambiguity"]),
                )
            )
    if not rows:
        return []
    header = [
        "measurement",
        "Δt (ms)",
        "matching tolerance (µm)",
        "max_speed (m/s)",
        "link radius (mm)",
        "particle spacing (mm)",
        "ambiguous links",
    ]
    return [
        "<h3>Linking</h3>",
        table(header, rows),
        "<p>The matching tolerance is 1.5 pixel footprints at the volume's centre, or 6 "
        "median ray distances of the matches where the calibration's triangulation error "
        "is larger, measured on the first snapshots unless the scenario gives it. "
        "The link radius is max_speed·Δt + 5σ_b; max_speed is measured on the links of "
        "the first snapshots at the smallest Δt unless the scenario gives it. The particle "
        "spacing is the median distance from a matched particle to its nearest neighbour; "
        "an ambiguous link had a second candidate within the radius (a Δt above "
        f"{100 * AMBIGUITY_WARNING:g} % is warned about).</p>",
    ]
