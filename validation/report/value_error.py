"""A measured value and its error as a figure prints them: "0.1300 ± 0.0018".

The error is given to two significant digits and the value to the same decimal place,
so that both have the precision the error allows: c2 = −0.6 ± 1.2 µm², not
"−1 ± 1"; ε = 0.1300 ± 0.0017, not "0.13 ± 0.0017". Every figure that prints a value
with its error uses :func:`value_error`.
"""

import math
from decimal import ROUND_HALF_UP, Decimal

__all__ = ["value_error"]

#: Written plainly while the value is below 10⁶ and the error's last digit shown is
#: no finer than 10⁻⁶ (0.13000 ± 0.00017); beyond, the pair shares a power of ten:
#: "(1.230 ± 0.045)×10⁻⁶".
_LARGEST_PLAIN = 5
_SMALLEST_PLAIN = -5

_SUPERSCRIPTS = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")
_MINUS = "−"  # U+2212, the minus sign (a hyphen is too short beside ±)


def _fixed(value: float, decimals: int) -> str:
    """``value`` rounded half away from zero to ``decimals`` decimal places (tens,
    hundreds… when negative), with a minus sign; −0 written 0."""
    rounded = Decimal(repr(value)).quantize(Decimal(1).scaleb(-decimals), ROUND_HALF_UP)
    text = f"{rounded:.{max(decimals, 0)}f}"
    if text.startswith("-"):
        text = text[1:] if rounded == 0 else _MINUS + text[1:]
    return text


def _error_exponent(error: float) -> int:
    """Decimal exponent of the error's first significant digit once it is rounded to
    two significant digits (0.0995 rounds to 0.10: exponent −1, not −2)."""
    exponent = math.floor(math.log10(error))
    if float(_fixed(error, 1 - exponent)) >= 10.0 ** (exponent + 1):
        exponent += 1
    return exponent


def value_error(value: float, error: float, unit: str = "") -> str:
    """``value ± error`` with the error to two significant digits and the value to the
    same decimal place.

    Parameters
    ----------
    value : float
        The measured value.
    error : float
        Its error (a standard error), ≥ 0.
    unit : str
        Appended after a space when given.

    Returns
    -------
    str
        E.g. ``value_error(0.13, 0.0017)`` → "0.1300 ± 0.0017", ``value_error(-0.63,
        1.23, "µm²")`` → "−0.6 ± 1.2 µm²", ``value_error(12345, 567)`` → "12350 ± 570".
        Very large or small numbers share a power of ten: ``value_error(1.23e-6,
        4.5e-8)`` → "(1.230 ± 0.045)×10⁻⁶". An error of 0 gives "value ± 0" (the value
        to 4 significant digits); a missing (non-finite or negative) error gives the
        value to 3 significant digits and "± ?"; a non-finite value "nan".
    """
    value, error = float(value), float(error)
    suffix = f" {unit}" if unit else ""
    if not math.isfinite(value):
        return f"{value}{suffix}"
    if not (math.isfinite(error) and error >= 0):
        return f"{_significant(value, 3)} ± ?{suffix}"
    if error == 0:
        return f"{_significant(value, 4)} ± 0{suffix}"
    exponent = _error_exponent(error)
    top = math.floor(math.log10(abs(value))) if value != 0 else exponent
    shared = max(top, exponent)
    if shared <= _LARGEST_PLAIN and exponent >= _SMALLEST_PLAIN:
        decimals = 1 - exponent
        return f"{_fixed(value, decimals)} ± {_fixed(error, decimals)}{suffix}"
    scale = 10.0**shared
    decimals = 1 - (exponent - shared)
    power = str(shared).translate(_SUPERSCRIPTS)
    pair = f"{_fixed(value / scale, decimals)} ± {_fixed(error / scale, decimals)}"
    return f"({pair})×10{power}{suffix}"


def _significant(value: float, digits: int) -> str:
    """``value`` to ``digits`` significant digits, with a minus sign."""
    text = f"{value:.{digits}g}"
    return _MINUS + text[1:] if text.startswith("-") else text
