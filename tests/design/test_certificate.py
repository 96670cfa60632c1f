"""Certificates: a NaN or infinite measurement never certifies, and worst() never drops a NaN."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from fdisyn.numerics.certificate import Certificate, Check, worst
from fdisyn.numerics.factorisation import co_inner_outer
from fdisyn.runtime.errors import CertificateError

NONFINITE = [math.nan, math.inf, -math.inf]


@pytest.mark.parametrize("relation", ["<=", ">="])
@pytest.mark.parametrize("bad", NONFINITE)
def test_a_non_finite_value_or_bound_fails(relation: str, bad: float) -> None:
    """Before, ``nan <= 1e-6`` was the only refusal: ``inf >= 0`` and a NaN bound passed."""
    assert Check("v", 0.5, 1.0 if relation == "<=" else 0.0, relation, "r").passed  # type: ignore[arg-type]
    assert not Check("v", bad, 1.0, relation, "r").passed  # type: ignore[arg-type]
    assert not Check("v", 0.5, bad, relation, "r").passed  # type: ignore[arg-type]
    cert = Certificate.of("design", [Check("ok", 0.0, 1.0, "<=", "r"), Check("gap", bad, 1.0, relation, "r")])  # type: ignore[arg-type]
    assert not cert.passed and cert.to_dict()["passed"] is False
    with pytest.raises(CertificateError, match="gap"):
        cert.require()


def test_worst_keeps_nan_wherever_it_stands() -> None:
    """``max(0.0, nan)`` is 0.0 in Python: the very swallow a certificate aggregate must not do."""
    rng = np.random.default_rng(0)
    for _ in range(200):
        vals = list(rng.standard_normal(int(rng.integers(1, 6))) * 10.0 ** rng.integers(-5, 5))
        assert worst(*vals) == max(vals)
        k = int(rng.integers(0, len(vals) + 1))
        assert math.isnan(worst(*vals[:k], math.nan, *vals[k:]))
    assert worst() == 0.0
    assert worst(1.0, math.inf) == math.inf


def test_co_inner_residual_reports_a_nan_second_term() -> None:
    """A co-inner factor whose second identity is NaN: the residual is NaN, not the first term."""
    fac = co_inner_outer(A=np.array([[0.5]]), B=np.array([[1.0]]), C=np.array([[1.0]]), D=np.array([[1.0]]))
    assert math.isfinite(fac.co_inner_residual())
    broken = dataclasses.replace(fac, G_i=dataclasses.replace(fac.G_i, A=np.full_like(fac.G_i.A, np.nan)))
    assert math.isnan(broken.co_inner_residual())


def test_a_failed_check_shows_enough_digits_to_see_its_violation() -> None:
    from fdisyn.numerics.certificate import distinct_digits

    bound = 0.951229424500714 + 1e-7
    with pytest.raises(CertificateError) as err:
        Certificate.of("d", [Check("spectral radius", bound + 2e-9, bound, "<=", "the decay bound")]).require()
    assert "spectral radius = 0.95122953 (must be <= 0.95122952: the decay bound)" in str(err.value)
    assert distinct_digits(1e-6, 1e-8) == ("1e-06", "1e-08")  # three digits when they already differ
    assert distinct_digits(1 + 2**-52, 1.0) == ("1.0000000000000002", "1")
    assert distinct_digits(float("nan"), 1.0) == ("nan", "1")
