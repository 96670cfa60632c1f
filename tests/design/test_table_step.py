"""A linear diagnoser's step as loops over constant tables (:func:`fdisyn.synthesis.linear_step._table_step`).

Truths: the table step gives the scalar step's values bit for bit (both add every product's terms in the same
order, and an unused warm-up gain contributes exact zeros) on seeded random plants and every detector, through
non-finite samples and a plant running at switch-on; a bank too large for straight-line code is written as tables,
compiled, and agrees with the NumPy reference at the pipeline's export tolerance.
"""

from __future__ import annotations

from pathlib import Path

import casadi as ca
import fdisyn
import numpy as np
import pytest
from fdisyn.app.bench import scaling_plant
from fdisyn.synthesis.linear_step import TABLE_INSTRUCTIONS, _scalar_step, _table_step, linear_step_function

from tests.helpers import random_plant


def _trace(gf, seed: int, n: int = 160) -> tuple[np.ndarray, np.ndarray]:  # noqa: ANN001 - a GainFile
    """Inputs and outputs of a plant already moving (an offset and a ramp), with non-finite samples in both."""
    rng = np.random.default_rng(seed)
    U = 3.0 + rng.standard_normal((n, gf.step.nu))
    Y = 5.0 + 0.01 * np.arange(n)[:, None] + rng.standard_normal((n, gf.step.ny))
    Y[40, 0] = np.nan
    U[41, 0] = np.inf
    Y[90:93, -1] = np.nan  # a gap, inside or after the warm-up
    Y[120, 0] = 1e300  # finite but absurd: the products overflow, the sample is skipped
    return U, Y


def _outputs(fn: ca.Function, gf, U: np.ndarray, Y: np.ndarray) -> list[np.ndarray]:  # noqa: ANN001
    out = fn.mapaccum("run", len(Y))(np.asarray(gf.step.init_state, float), U.T, Y.T)
    return [np.asarray(o) for o in out]


@pytest.mark.parametrize(
    ("seed", "options"),
    [
        (1, {}),
        (2, {"detector": "wssr", "window": 5}),
        (3, {"detector": "cusum", "arl0": 100.0}),
        (4, {"detector": "glr", "arl0": 100.0}),
        (5, {"detector": "chi2", "arl0": 100.0}),
        (6, {"detector": "cusum", "arl0": 100.0, "shifts": [0.5, 2.0]}),
    ],
)
def test_the_table_step_gives_the_scalar_steps_values_bit_for_bit(seed: int, options: dict) -> None:
    plant = random_plant(seed, n=4, p=4, q=1)
    gf = fdisyn.design(plant, method="kalman_uio", bank={"a": list(plant.outputs[:3]), "b": list(plant.outputs[1:])}, **options)
    U, Y = _trace(gf, seed)
    scalar, table = _scalar_step(gf), _table_step(gf)
    assert scalar.is_a("SXFunction") and table.is_a("MXFunction")
    # the equilibrium, the warm-up gain's product and the correction run only on the samples that need them, each
    # a switch that generators of the same shapes share: one per kind and shape, not one per generator
    switches = [f.name() for f in table.find_functions() if f.name().startswith("only_if")]
    warm_shapes = {(int(g.warmup), g.n_state, g.n_residual) for g in gf.generators}
    assert all(g.warmup for g in gf.generators)
    assert sorted(switches) == ["only_if_affine"] * 2 + ["only_if_warm_product"] * len(warm_shapes)
    for x, z in zip(_outputs(scalar, gf, U, Y), _outputs(table, gf, U, Y), strict=True):
        assert np.array_equal(x, z, equal_nan=True)
    assert linear_step_function(gf).is_a("SXFunction")  # a small step stays straight-line code


@pytest.mark.filterwarnings("ignore:overflow encountered:RuntimeWarning")  # the trace's absurd sample, on purpose
def test_a_bank_beyond_straight_line_code_is_compiled_as_tables_and_agrees_with_the_reference(tmp_path: Path) -> None:
    """A 40-state plant on 10 sensors with a bank of four minimum-variance UIOs (reduced problems of 38 states: the
    Riccati gain, certified by the optimality condition): its step is far beyond :data:`TABLE_INSTRUCTIONS`, so it
    is written as tables; compiled, it agrees with the NumPy reference (an independent implementation) to the
    pipeline's export tolerance on a trace of a plant moving at switch-on, with non-finite samples."""
    from fdisyn.app.pipeline import EXPORT_TOL, _casadi_run, _relative, _rounding_scale, _scale_rows, _state_scale
    from fdisyn.synthesis.kinds import reference_run

    plant, bank = scaling_plant(40, 11, sensors=10, generators=4)
    gf = fdisyn.design(plant, method="kalman_uio", bank=bank)
    assert gf.certificate["generators"][0]["info"]["gain_route"].startswith("Riccati")
    fn = linear_step_function(gf)
    assert fn.is_a("MXFunction")
    fdisyn.export(gf, tmp_path / "big")
    compiled = fdisyn.load(tmp_path / "big")
    U, Y = _trace(gf, 3, n=300)
    c_res = compiled.run(U, Y)
    ref = reference_run(gf, U, Y)
    assert ref is not None
    cas, states = _casadi_run(fn, gf.step.init_state, U, Y, _scale_rows(gf))
    s_r, s_j = _rounding_scale(gf, states, cas, U, Y)
    assert _relative(c_res.r, ref.r, s_r) <= EXPORT_TOL
    assert _relative(c_res.J, ref.J, s_j) <= EXPORT_TOL
    assert np.array_equal(c_res.alarm, ref.alarm) and np.array_equal(c_res.isolated, ref.isolated)
    assert np.array_equal(c_res.status, ref.status)
    assert c_res.alarm.any()  # the trace's ramp is seen: the comparison covers alarms and the isolation test
    code = (tmp_path / "big" / "c" / f"{gf.name}_casadi.c").read_text()
    assert "casadi_mtimes_dense" in code
    assert _relative(c_res.state, ref.state, _state_scale(gf, ref.state, s_r)) <= EXPORT_TOL
