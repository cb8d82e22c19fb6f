"""The run report's table of the whole sheet's yield by region of the sheet: depth
across the sheet, place against its X, Y outline and against the calibrated volume
(:mod:`validation.truth.sheet_regions`; docs/run.md §10)."""

from validation.report.html_parts import number, percent, table

__all__ = ["sheet_region_table"]


def sheet_region_table(results: dict) -> list[str]:
    """Per region of the sheet: its particles, and each scored measurement's yield and
    loss there (nothing for a run whose matching scores hold no regions)."""
    scored = {v: m["sheet_regions"] for v, m in results["matching"].items() if "sheet_regions" in m}
    if not scored:
        return []
    first = next(iter(scored.values()))
    rows = []
    for i, region in enumerate(first):
        cells = [region["group"], region["region"], region["particles"]]
        for by_region in scored.values():
            row = by_region[i]
            loss = "" if row["loss"] is None else f" ({percent(row['loss'])})"
            cells.append(number(row["yield"], 4) + loss)
        rows.append(cells)
    header = ["group", "region", "particles", *(f"{v}: yield (loss)" for v in scored)]
    return [
        "<h3>Yield by region of the sheet</h3>",
        table(header, rows),
        "<p>The particles of the whole sheet's yield (lit and on every camera's sensor, "
        "frame a of the scored snapshots), cut by depth across the sheet (its Gaussian "
        "wings are dim), by their place against the sheet's X, Y outline and against "
        "the calibrated volume (the plate's dots over the traverse: the model-free "
        "calibration has no rays beyond it). The loss is the particles a region loses "
        "over the whole sheet's, so the losses of each group add up to one minus the "
        "sheet yield. The last rows count the particles fewer cameras image, which the "
        "sheet yield leaves out.</p>",
    ]
