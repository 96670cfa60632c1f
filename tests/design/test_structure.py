"""The achievable fault signatures (``fdisyn.structure_matrices``, ``fdisyn analyse``) against truths that do not
use the system pencil: ranks of the transfer matrices at random complex points, polynomial null vectors found from
point values, faults planted to be hidden or to vanish at a frequency, and invariance under the user's units."""

from __future__ import annotations

import itertools
import json

import numpy as np
import pytest

import fdisyn
from fdisyn.app.cli import main
from fdisyn.runtime.errors import ArgumentError
from fdisyn.synthesis.structure import analyse_structure, check_structure, fault_entries, structure_matrices

POINT_RANK_TOL = 1e-9
"""Relative singular-value level below which a transfer matrix at a random point counts as rank deficient: the
seeded plants below are well conditioned (the smallest nonzero singular value at a point on the circle of radius
1.3 stays above 1e-4 of the largest), so round-off (~1e-15) and a true rank are far apart."""


def _plant(seed: int, *, discrete: bool = True) -> fdisyn.LinearPlant:
    rng = np.random.default_rng(seed)
    n, p = int(rng.integers(1, 6)), int(rng.integers(1, 5))
    m, q, nc = int(rng.integers(0, 3)), int(rng.integers(0, min(p, 3))), int(rng.integers(0, 3))
    a = rng.standard_normal((n, n))
    a = a * (0.9 / max(abs(np.linalg.eigvals(a)))) if discrete else a - (max(np.linalg.eigvals(a).real) + 0.5) * np.eye(n)
    d = rng.standard_normal((p, m)) if rng.random() < 0.5 else np.zeros((p, m))
    b, c, e, fx = rng.standard_normal((n, m)), rng.standard_normal((p, n)), rng.standard_normal((n, q)), rng.standard_normal((n, nc))
    # unknown inputs and component faults that reach the sensors directly too (Dd, Df), or only them
    dd = rng.standard_normal((p, q)) if rng.random() < 0.4 else np.zeros((p, q))
    df = rng.standard_normal((p, nc)) if rng.random() < 0.4 else np.zeros((p, nc))
    if nc and rng.random() < 0.2:
        fx[:, 0], df[:, 0] = 0.0, rng.standard_normal(p)  # a fault of the sensors only
    return fdisyn.LinearPlant.create(
        A=a, B=b, C=c, D=d, E=e, Fx=fx, Dd=dd, Df=df, Ts=0.1 if discrete else None, component_faults=[f"c{i}" for i in range(nc)],
    )


def _transfer(plant: fdisyn.LinearPlant, b: np.ndarray, d: np.ndarray, z: complex) -> np.ndarray:
    n = plant.n
    x = np.linalg.solve(z * np.eye(n) - np.asarray(plant.A), b) if n else np.zeros((0, b.shape[1]))
    return np.asarray(plant.C) @ x + d


def _point_rank(plant: fdisyn.LinearPlant, cols: list[int], points: np.ndarray) -> int:
    """Rank of ``[G_d G_f,cols]`` at random points: its normal rank (generic points are neither poles nor zeros)."""
    _, bf, df = fault_entries(plant)
    b = np.hstack([np.asarray(plant.E), bf[:, cols]])
    d = np.hstack([np.asarray(plant.Dd), df[:, cols]])
    if b.shape[1] == 0:
        return 0
    best = 0
    for z in points:
        s = np.linalg.svd(_transfer(plant, b, d, z), compute_uv=False)
        best = max(best, int(np.sum(s > POINT_RANK_TOL * s[0])) if s.size and s[0] > 0 else 0)
    return best


def _points(seed: int, k: int = 3) -> np.ndarray:
    return 1.3 * np.exp(1j * np.random.default_rng(seed).uniform(0.2, 2.9, k))


def _rows_by_points(plant: fdisyn.LinearPlant, points: np.ndarray) -> set[tuple[int, ...]]:
    """Every subset of faults decoupled: the row of the faults still seen (rank grows when the fault is added)."""
    nf = plant.p + len(plant.component_faults)
    rows = set()
    for r in range(nf + 1):
        for dec in itertools.combinations(range(nf), r):
            base = _point_rank(plant, list(dec), points)
            row = tuple(int(j not in dec and _point_rank(plant, [*dec, j], points) > base) for j in range(nf))
            if any(row):
                rows.add(row)
    return rows


@pytest.mark.parametrize("seed", range(40))
def test_the_weak_rows_are_those_the_ranks_at_random_points_give(seed: int) -> None:
    plant = _plant(seed, discrete=seed % 3 != 0)
    got = structure_matrices(plant)
    assert got.dtype.kind == "i" and got.shape[1] == plant.p + len(plant.component_faults)
    assert {tuple(int(v) for v in row) for row in got} == _rows_by_points(plant, _points(seed))
    assert len({tuple(row) for row in got}) == len(got)  # each row once


def _least_order_by_points(plant: fdisyn.LinearPlant, row: np.ndarray, points: np.ndarray) -> int:
    """The smallest ``k`` with a polynomial row ``v(λ) = Σ vᵢ λⁱ`` of degree ``k`` (over ``[y; u]``) that annihilates
    ``[G_u G_d G_f,zeros; I 0 0]`` at enough points to vanish identically (``v G_e`` is rational with a denominator of
    degree ``n`` and a numerator of degree at most ``k + n``) and sees every fault of the row at a test point."""
    _, bf, df = fault_entries(plant)
    zeros = [j for j in range(len(row)) if row[j] == 0]
    ones = [j for j in range(len(row)) if row[j] == 1]
    n, p, m = plant.n, plant.p, plant.m
    b = np.hstack([np.asarray(plant.B), np.asarray(plant.E), bf[:, zeros]])
    d = np.hstack([np.asarray(plant.D), np.asarray(plant.Dd), df[:, zeros]])
    for k in range(n + 1):
        fit = np.exp(1j * np.linspace(0.1, 3.0, 2 * (k + n) + 6)) * 1.2
        blocks = []
        for z in fit:
            ge = np.vstack([_transfer(plant, b, d, z), np.hstack([np.eye(m), np.zeros((m, b.shape[1] - m))])])
            blocks.append(np.vstack([z**i * ge for i in range(k + 1)]))
        big = np.hstack(blocks)
        big = np.hstack([big.real, big.imag])
        u, s, _ = np.linalg.svd(big, full_matrices=True)
        null = u[:, int(np.sum(s > 1e-9 * s[0])) :].T if big.size else np.eye((k + 1) * (p + m))
        if null.shape[0] == 0:
            continue
        seen = True
        for j in ones:
            g = _transfer(plant, bf[:, [j]], df[:, [j]], points[0])[:, 0]
            vals = sum((null[:, i * (p + m) : i * (p + m) + p] * points[0] ** i for i in range(k + 1)), np.zeros((null.shape[0], p), complex))
            seen &= bool(np.linalg.norm(vals @ g) > 1e-7 * np.linalg.norm(vals) * np.linalg.norm(g))
        if seen:
            return k
    raise AssertionError("no filter sees the row")


@pytest.mark.parametrize("seed", range(12))
def test_least_orders_are_the_smallest_degree_of_a_polynomial_null_vector(seed: int) -> None:
    plant = _plant(100 + seed)
    res = analyse_structure(plant)
    for row, order in zip(res.rows, res.least_orders, strict=True):
        assert order == _least_order_by_points(plant, row, _points(seed)), (row, order)
    # fdichkspec on the same rows: achievable, with the same least orders
    checked = check_structure(plant, res.rows)
    assert [c["least_order"] for c in checked] == list(res.least_orders) and all(c["achievable"] for c in checked)


def _with_faults(plant: fdisyn.LinearPlant, fx: np.ndarray) -> fdisyn.LinearPlant:
    return fdisyn.LinearPlant.create(
        A=plant.A, B=plant.B, C=plant.C, D=plant.D, E=plant.E, Fx=fx, Ts=plant.Ts, component_faults=[f"c{i}" for i in range(fx.shape[1])]
    )


def test_a_fault_along_an_unknown_input_is_never_seen_and_one_along_a_known_input_always_can_be() -> None:
    rng = np.random.default_rng(5)
    n, p = 4, 3
    a = rng.standard_normal((n, n))
    a *= 0.8 / max(abs(np.linalg.eigvals(a)))
    plant = fdisyn.LinearPlant.create(A=a, B=rng.standard_normal((n, 1)), C=rng.standard_normal((p, n)), E=rng.standard_normal((n, 1)), Ts=0.1)
    both = _with_faults(plant, np.hstack([plant.E, plant.B]))
    rows = structure_matrices(both)
    assert not rows[:, p].any()  # hidden by the decoupling of d
    assert rows[:, p + 1].any()  # a known input is subtracted, not decoupled
    bad = check_structure(both, [[0, 0, 0, 1, 0]])
    assert not bad[0]["achievable"] and "c0" in bad[0]["why"]


@pytest.mark.parametrize("discrete", [True, False])
def test_a_fault_without_a_constant_response_has_no_strong_row_at_zero_frequency(discrete: bool) -> None:
    """A component fault ``Fx = (I − A) v`` (discrete) or ``A v`` (continuous) with ``C v = 0`` has ``G_f(1) = C v = 0``
    (``G_f(0) = 0``): seen by the weak structure, never by the strong one at 0 rad/s, and the strong rows are the
    weak rows without it; at another frequency nothing vanishes."""
    rng = np.random.default_rng(7 + discrete)
    n, p = 5, 3
    a = rng.standard_normal((n, n))
    a = a * (0.8 / max(abs(np.linalg.eigvals(a)))) if discrete else a - (max(np.linalg.eigvals(a).real) + 0.5) * np.eye(n)
    c = rng.standard_normal((p, n))
    v = np.linalg.svd(c)[2][-1]  # C v = 0
    fx = ((np.eye(n) - a) @ v if discrete else a @ v)[:, None]
    plant = fdisyn.LinearPlant.create(A=a, C=c, E=rng.standard_normal((n, 1)), Fx=np.hstack([fx, rng.standard_normal((n, 1))]),
                                      Ts=0.1 if discrete else None, component_faults=["creep", "leak"])
    weak = structure_matrices(plant)
    strong = analyse_structure(plant, kind="strong")
    assert weak[:, p].any() and not strong.rows[:, p].any()
    assert {tuple(r) for r in strong.rows} == {tuple(r) for r in weak if r[p] == 0}
    assert strong.frequencies == (0.0,)
    other = structure_matrices(plant, kind="strong", frequencies=[1.0])
    assert {tuple(r) for r in other} == {tuple(r) for r in weak}
    refused = check_structure(plant, [[1, 1, 1, 1, 0]], kind="strong")[0]
    assert not refused["achievable"] and "creep" in refused["why"]


@pytest.mark.parametrize("seed", range(8))
def test_the_users_units_do_not_change_the_structure(seed: int) -> None:
    """Outputs, inputs and states rescaled by factors from 1e-4 to 1e4: the same rows, least orders and strong rows."""
    plant = _plant(200 + seed)
    rng = np.random.default_rng(seed)
    so = 10.0 ** rng.uniform(-4, 4, plant.p)
    su = 10.0 ** rng.uniform(-4, 4, plant.m)
    sx = 10.0 ** rng.uniform(-4, 4, plant.n)
    scaled = fdisyn.LinearPlant.create(
        A=np.diag(1 / sx) @ plant.A @ np.diag(sx), B=np.diag(1 / sx) @ plant.B @ np.diag(su), C=np.diag(so) @ plant.C @ np.diag(sx),
        D=np.diag(so) @ plant.D @ np.diag(su), E=np.diag(1 / sx) @ plant.E, Fx=np.diag(1 / sx) @ plant.Fx, Ts=plant.Ts,
        Dd=np.diag(so) @ plant.Dd, Df=np.diag(so) @ plant.Df, component_faults=plant.component_faults,
    )
    a, b = analyse_structure(plant), analyse_structure(scaled)
    assert np.array_equal(a.rows, b.rows) and a.least_orders == b.least_orders
    assert np.array_equal(structure_matrices(plant, kind="strong"), structure_matrices(scaled, kind="strong"))


def test_a_continuous_plant_has_the_weak_structure_of_its_exact_sampling() -> None:
    for seed in range(6):
        plant = _plant(300 + seed, discrete=False)
        assert np.array_equal(structure_matrices(plant), structure_matrices(plant.discretise(0.05)))


def test_bad_arguments_are_refused_in_one_line() -> None:
    plant = _plant(3)
    nf = plant.p + len(plant.component_faults)
    with pytest.raises(ArgumentError, match="kind must be 'weak' or 'strong'"):
        structure_matrices(plant, kind="Strong")  # type: ignore[arg-type]
    with pytest.raises(ArgumentError, match="give kind='strong'"):
        structure_matrices(plant, frequencies=[0.0])
    with pytest.raises(ArgumentError, match="finite numbers ≥ 0"):
        structure_matrices(plant, kind="strong", frequencies=[float("nan")])
    with pytest.raises(ArgumentError, match="above the Nyquist frequency"):
        structure_matrices(plant, kind="strong", frequencies=[100.0])
    with pytest.raises(ArgumentError, match=f"rows of {nf} entries"):
        check_structure(plant, [[1] * (nf + 1)])
    integrator = fdisyn.LinearPlant.create(A=[[1.0, 0.1], [0.0, 1.0]], C=[[1.0, 0.0]], Ts=0.1)
    with pytest.raises(ArgumentError, match="is a pole of the plant"):
        structure_matrices(integrator, kind="strong")
    with pytest.raises(ArgumentError, match="needs a linear plant"):
        structure_matrices("plant")


def test_the_root_package_offers_the_analysis() -> None:
    plant = fdisyn.LinearPlant.create(A=[[0.5, 0.0], [0.0, 0.3]], C=[[1.0, 0.0], [0.0, 1.0]], Ts=0.1)
    assert fdisyn.structure_matrices(plant).tolist() == [[1, 1], [1, 0], [0, 1]]
    assert fdisyn.analyse_structure(plant).decoupled == ((), ("y1",), ("y0",))


def test_fdisyn_analyse_prints_the_rows_with_their_least_orders(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["analyse", "wind_turbine"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("wind_turbine: 4 faults, weak structure: 11 achievable specification(s)")
    assert out[1].split()[:4] == ["omega_r_m1", "omega_r_m2", "omega_g_m1", "omega_g_m2"] and "least order" in out[1]
    assert len(out) == 3 + 11
    assert main(["analyse", "wind_turbine", "--strong", "--frequencies", "0,1", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["kind"] == "strong" and doc["frequencies_rad_s"] == [0.0, 1.0] and doc["domain"] == "discrete"
    assert all(set(r) == {"signature", "least_order", "basis_size", "basis_order", "decoupled", "gap"} for r in doc["rows"])
    assert doc["pole"] == 0.5 and all(r["gap"] == "inf" or r["gap"] > 0 for r in doc["rows"])


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["ship_propulsion"], "needs a linear plant"),
        (["wind_turbine", "--frequencies", "0"], "add --strong"),
        (["wind_turbine", "--strong", "--frequencies", "0,x"], "'x' is not a number"),
    ],
)
def test_fdisyn_analyse_refuses_in_one_line(args: list[str], message: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["analyse", *args]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
