"""A value and its error on a figure: the error to two significant digits, the value to
the same decimal place."""

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from validation.report.value_error import value_error


@pytest.mark.parametrize(
    ("value", "error", "unit", "expected"),
    [
        # The user's cases: a value and its error at the same precision.
        (0.13, 0.0017, "", "0.1300 ± 0.0017"),
        (-0.63, 1.23, "µm²", "−0.6 ± 1.2 µm²"),
        (0.31, 0.44, "µm²", "0.31 ± 0.44 µm²"),
        (41.2, 9.04, "µm²", "41.2 ± 9.0 µm²"),
        (29.4, 2.04, "", "29.4 ± 2.0"),
        # The error rounds up to the next decade: one decimal place fewer.
        (0.5, 0.0995, "", "0.50 ± 0.10"),
        (3.14159, 0.996, "", "3.1 ± 1.0"),
        # Errors of tens and hundreds: the value to the tens.
        (12345.0, 567.0, "", "12350 ± 570"),
        (-1234.0, 56.0, "", "−1234 ± 56"),
        # Half away from zero, as a reader rounds.
        (0.125, 0.01, "", "0.125 ± 0.010"),
        (0.1235, 0.0011, "", "0.1235 ± 0.0011"),
        (2.25, 0.15, "", "2.25 ± 0.15"),
        (2.255, 0.15, "", "2.26 ± 0.15"),
        # A value smaller than its last digit: 0, not −0.
        (-0.004, 0.3, "", "0.00 ± 0.30"),
        (-0.04, 0.3, "", "−0.04 ± 0.30"),
        # Very small or large: a shared power of ten.
        (1.23e-6, 4.5e-8, "m", "(1.230 ± 0.045)×10⁻⁶ m"),
        (1.0e7, 3.0e5, "", "(1.000 ± 0.030)×10⁷"),
        (0.13, 0.00017, "", "0.13000 ± 0.00017"),
        # No error, or none known.
        (0.0, 0.0, "", "0 ± 0"),
        (0.123456, 0.0, "", "0.1235 ± 0"),
        (3.0, math.nan, "", "3 ± ?"),
        (3.0, -1.0, "", "3 ± ?"),
    ],
)
def test_the_error_sets_the_precision(value, error, unit, expected):
    assert value_error(value, error, unit) == expected


def test_a_missing_value_says_so():
    assert value_error(math.nan, 1.0, "m") == "nan m"


@given(
    st.floats(-1e5, 1e5, allow_nan=False),
    st.floats(1e-5, 1e4, allow_nan=False),
)
def test_two_significant_digits_of_error_and_the_value_to_the_same_place(value, error):
    text = value_error(value, error)
    shown_value, shown_error = text.replace("−", "-").split(" ± ")
    # The error's last digit shown is its second significant one…
    unit = 10.0 ** (math.floor(math.log10(float(shown_error))) - 1)
    assert float(shown_error) / unit == pytest.approx(round(float(shown_error) / unit))
    places = max(0, -round(math.log10(unit)))
    assert len(shown_error.partition(".")[2]) == places
    # …and the value's too.
    assert len(shown_value.partition(".")[2]) == places
    steps = float(shown_value) / unit
    assert steps == pytest.approx(round(steps), rel=1e-12, abs=1e-6)
    # Rounded, not truncated: within half a unit of that digit (and a float's ulps).
    slack = 1e-9 * unit + 1e-14 * abs(value)
    assert abs(float(shown_value) - value) <= 0.5 * unit + slack
    assert abs(float(shown_error) - error) <= 0.5 * unit + slack
