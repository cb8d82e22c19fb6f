"""The audit's table, as docs/claims.md §6 prints it (Markdown)."""

from collections import Counter

from validation.audit.runner import AuditRow


def audit_table(rows: list[AuditRow]) -> str:
    """A Markdown table of the rows and a line of counts."""
    lines = [
        "| setting | perturbation | outcome | killed by, or the claim moved most |",
        "|---|---|---|---|",
    ]
    for row in rows:
        module, _, path = row.audited.target.partition(":")
        name = path if row.audited.is_field else f"{module.rpartition('.')[2]}.{path}"
        if row.verdict == "not run":
            lines.append(f"| `{name}` | — | not run | {row.audited.reason} |")
        elif row.killed_by:
            killers = ", ".join(f"`{c}`" for c in row.killed_by)
            lines.append(f"| `{name}` | {row.label} | killed | {killers} |")
        else:
            moved = (
                f"`{row.moved}`: {row.effect:.2f} of its room" if row.moved else "no claim moved"
            )
            lines.append(f"| `{name}` | {row.label} | {row.verdict} | {moved} |")
    run = [r for r in rows if r.verdict != "not run"]
    counts = Counter(r.verdict for r in run)
    lines.append("")
    lines.append(
        f"{len(run)} perturbations of {len({r.audited.target for r in run})} settings run: "
        f"{counts['killed']} killed, {counts['within a tenth']} within a tenth of their "
        f"room, {counts['gap']} gaps; {sum(r.verdict == 'not run' for r in rows)} entries "
        "not run, each with its reason."
    )
    return "\n".join(lines)
