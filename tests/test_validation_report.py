"""validate's summary: the verdict in words first, and percentages that never round a bias to
zero."""

import pytest

from validation.report import _pct, _verdict_lines


@pytest.mark.parametrize("rel, text", [(4.7e-5, "+0.0047 %"), (-0.0123, "-1.23 %"),
                                       (0.5, "+50.00 %"), (2.3e-10, "+0.0000 %"),
                                       (0.0, "0 %"), (float("nan"), "n/a")])
def test_percent_keeps_two_significant_digits(rel, text):
    assert _pct(rel) == text


def test_the_verdict_says_within_or_outside_in_words():
    inside = _verdict_lines({"u_mu": 1e-7, "z_budget": 1.38, "within_U": True})
    assert "agrees with the truth within U(mu)" in inside[0] and "1.38 u(mu)" in inside[0]
    outside = _verdict_lines({"u_mu": 1e-7, "z_budget": -3.14, "within_U": False})
    assert "OUTSIDE U(mu)" in outside[0] and "3.1 u(mu)" in outside[0]
    assert _verdict_lines({"mu_stderr": 1e-7}) == []
