"""The report's section on a Navier–Stokes flow: the DNS's own checks and the Δt³ term
(:mod:`validation.run.dns_checks`)."""

from validation.report.html_parts import number, table


def _mark(passed: bool) -> str:
    return "<span class='pass'>PASS</span>" if passed else "<span class='fail'>FAIL</span>"


def dns_html(results: dict, scenario) -> list[str]:
    """The ``dns`` section of results.json as HTML (nothing for a KS flow)."""
    dns = results.get("dns")
    if dns is None:
        return []
    f, budget, kh = results["flow"], dns["energy_budget"], dns["karman_howarth"]
    parts = ["<h2>Navier–Stokes flow: the DNS and the Δt³ term</h2>"]
    parts.append(
        table(
            ["grid", "box (mm)", "R_λ", "u' (m/s)", "η (µm)", "T_L (s)", "k_max η"],
            [
                (
                    f"{f['grid']}³",
                    number(f["box_side"] * 1e3),
                    number(f["r_lambda_measured"]),
                    number(f["u_rms"]),
                    number(f["eta"] * 1e6),
                    number(f["eddy_time"]),
                    number(f["kmax_eta_measured"]),
                )
            ],
        )
    )
    parts.append(
        f"<p>{_mark(budget['passed'])} energy budget: mean dissipation / injection "
        f"{number(budget['dissipation_over_injection'])} over "
        f"{number(budget['window_eddy_times'], 3)} T_L (within ±{budget['tolerance']:.0%}). "
        f"{_mark(kh['passed'])} Kármán–Howarth: S3 against 6ν dS2/dr minus the forcing "
        f"term, largest residual {number(kh['max_residual_in_se'], 3)} standard errors below "
        f"a quarter box (at most {kh['tolerance_se']:g}).</p>"
    )
    flux = dns["flux"]
    rows = [
        (number(r, 3), number(a, 3), number(b, 3))
        for r, a, b in zip(
            flux["r_over_eta"],
            flux["du_da_over_minus_2eps"],
            flux["dul_dal_over_minus_2eps"],
            strict=True,
        )
    ]
    parts.append("<p>Energy flux at the grid's separations (−2ε in an inertial range):</p>")
    parts.append(table(["r/η", "⟨δu·δa⟩/(−2ε)", "⟨δu_L δa_L⟩/(−2ε)"], rows))
    dt3 = dns["dt3_bias"]
    if dt3 is None:
        parts.append("<p>The Δt³ term needs every Δt from a shared first frame.</p>")
        return parts
    parts.append(
        f"<p>{_mark(dt3['passed'])} (informative) bias of c1 on the true trajectories "
        f"against the sample truth of its pairs, ± its paired bootstrap error, with the "
        f"prediction γβ/S2 (γ = {number(dt3['gain_s'] * 1e3, 3)} ms unweighted; and with "
        f"the γ of the fit's weights); Σz² = {number(dt3['chi2'], 3)} (at most "
        f"{dt3['chi2_limit']:g}):</p>"
    )

    def cell(entry):
        return f"{100 * entry['bias']:+.2f} ± {100 * entry['se']:.2f} %"

    rows = [
        (
            number(row["r_over_eta"], 3),
            cell(row["standard"]),
            cell(row["midpoint"]),
            f"{100 * row['predicted']:+.2f} %",
            f"{100 * row['predicted_weighted']:+.2f} %",
            number(row["z"], 3),
        )
        for row in dt3["rows"]
    ]
    parts.append(
        table(
            ["r/η", "start binning", "chord midpoint", "γβ/S2", "γ_w β/S2", "z (start)"],
            rows,
        )
    )
    return parts
