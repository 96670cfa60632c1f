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
