"""Small pieces of the HTML reports: numbers and tables."""

import html

import numpy as np


def number(value, digits: int = 4) -> str:
    """A value for a table cell: "–" for None, yes/no, integers whole, others to
    ``digits`` significant digits."""
    if value is None:
        return "–"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, int | np.integer):
        return str(value)
    return f"{value:.{digits}g}"


def table(header, rows) -> str:
    """An HTML table: one header row of ``header``, then ``rows`` (cells escaped)."""
    head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
    body = "".join(
        "<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in row) + "</tr>" for row in rows
    )
    return f"<table><tr>{head}</tr>{body}</table>"


def percent(value: float | None) -> str:
    """A fraction as a percentage for a table cell, to 3 significant digits ("–" for None)."""
    return "–" if value is None else f"{100 * value:.3g} %"
