"""Admittance filters: exact ZOH matrices and step responses (SPEC §5)."""

from __future__ import annotations

import admit_rs as ar
import numpy as np
import pytest
from scipy.signal import cont2discrete


@pytest.mark.parametrize(
    ("m", "b", "k", "ka"),
    [
        (1.0, 800.0, 400.0, 0.1),
        (1.0, 800.0, 0.0, 0.1),
        (1.0, 200.0, 0.0, 2.0),
        (2.5, 30.0, 90.0, 1.0),
    ],
)
@pytest.mark.parametrize("period", [1e-3, 5e-3])
def test_zoh_matches_scipy(m, b, k, ka, period):
    a = np.array([[0.0, 1.0], [-k / m, -b / m]])
    bm = np.array([[0.0], [ka / m]])
    ad_ref, bd_ref, *_ = cont2discrete((a, bm, np.eye(2), np.zeros((2, 1))), period, method="zoh")
    ad, bd = ar.AdmittanceFilter(m=m, b=b, k=k, ka=ka).discretize(period)
    np.testing.assert_allclose(ad, ad_ref, rtol=0, atol=1e-13)
    np.testing.assert_allclose(bd, bd_ref[:, 0], rtol=0, atol=1e-15)


def test_scheme1_step_response_is_analytic():
    """k_a/(s² + 800 s + 400) for e_f = 10: overdamped, exact at the samples under ZOH."""
    filt = ar.AdmittanceFilter.scheme1(b=800.0, k=400.0, ka=0.1)
    t = np.arange(5000) * 1e-3
    out = filt.response(np.full(t.size, 10.0), 1e-3)
    p1, p2 = np.roots([1.0, 800.0, 400.0])
    final = 0.1 * 10.0 / 400.0
    exact = final * (1 + (p2 * np.exp(p1 * t) - p1 * np.exp(p2 * t)) / (p1 - p2))
    np.testing.assert_allclose(out["x_a"], exact, rtol=0, atol=1e-12)
    # Feed-forward acceleration of the current sample: (k_a e_f − b ẋ_a − k x_a)/m.
    np.testing.assert_allclose(
        out["xa_ddot"], 0.1 * 10.0 - 800.0 * out["xa_dot"] - 400.0 * out["x_a"], atol=1e-12
    )


def test_scheme2_step_response_is_a_ramp_after_the_transient():
    """k_a/(s² + b s): x_a(t) = (k_a e/b)(t − (1 − e^{−bt})/b)."""
    b, ka, e = 400.0, 1.0, 3.0
    t = np.arange(2000) * 1e-3
    out = ar.AdmittanceFilter.scheme2(b=b, ka=ka).response(np.full(t.size, e), 1e-3)
    exact = ka * e / b * (t - (1 - np.exp(-b * t)) / b)
    np.testing.assert_allclose(out["x_a"], exact, rtol=0, atol=1e-13)
    np.testing.assert_allclose(out["xa_dot"], ka * e / b * (1 - np.exp(-b * t)), atol=1e-13)


def test_filter_is_strictly_proper():
    out = ar.AdmittanceFilter.scheme2(b=800.0, ka=1.0).response([5.0, 0.0, 0.0], 1e-3)
    assert out["x_a"][0] == 0.0 and out["xa_dot"][0] == 0.0
    assert out["xa_ddot"][0] == 5.0
    assert out["x_a"][1] > 0.0


def test_scheme_constructors():
    assert ar.AdmittanceFilter.scheme1() == ar.AdmittanceFilter(m=1.0, b=800.0, k=400.0, ka=0.1)
    assert ar.AdmittanceFilter.scheme2(b=200.0, ka=2.0).k == 0.0
