"""The magnitude bound of a gain file's numbers: huge entries cannot overflow the consistency checks.

Bases are the gain files committed under ``reports/`` (designed by ``fdisyn reproduce``; no design runs
here). A seeded fuzzer sets numeric entries the reader validates to ±1e308, ±1e200, values just inside
and just outside :data:`MAX_MAGNITUDE`, and asserts that each tampered file is either refused with a
:class:`GainFileError` naming the field, or — if accepted — that every consistency relation holds,
recomputed in extended precision (where 1e308² does not overflow), at finite values.
"""

from __future__ import annotations

import copy
import json
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fdisyn.runtime.errors import GainFileError
from fdisyn.runtime.gainfile import GainFile, read_gain_file
from fdisyn.runtime.schema import MAX_MAGNITUDE

ROOT = Path(__file__).resolve().parents[2]
GAINS = sorted((ROOT / "reports").glob("*/gains/*.json"))
LINEAR = [ROOT / "reports" / "wind_turbine" / "gains" / f"wind_turbine_kalman_uio{s}.json" for s in ("", "_chi2", "_cusum", "_glr")] + [
    ROOT / "reports" / "turbofan" / "gains" / "turbofan_grouped_wssr.json",
    ROOT / "reports" / "sampled_data_example" / "gains" / "sampled_data_example_lmi.json",
]
SEED = 20240624
MUTATIONS = 300
EDGE = MAX_MAGNITUDE * (1 + 1e-12)
VALUES = (1e308, -1e308, 1.7976931348623157e308, 1e200, -1e200, 1e151, EDGE, -EDGE, MAX_MAGNITUDE, -MAX_MAGNITUDE, 0.999 * MAX_MAGNITUDE, 1e100, -1e100)
"""Huge numbers: beyond the bound (refused), at and just inside it (checked for consistency)."""
_L = np.longdouble


def _write(tmp_path: Path, doc: Any, name: str = "gains.json") -> Path:
    p = tmp_path / name
    p.write_text(json.dumps(doc), encoding="utf-8")
    return p


_VALIDATED = {
    "plant": ("A", "B", "C", "D", "E", "Q", "R"),
    "generators": ("Ar", "Bu", "By", "Cr", "Du", "Dy", "Xu", "Xy"),
    "evaluators": ("P_f", "threshold", "Sigma_r", "W", "directions", "drift", "information"),
    "step": ("init_state",),
}


def _numeric_paths(doc: dict[str, Any]) -> list[tuple[Any, ...]]:
    """Paths to the numbers the reader validates (not the informational certificate, provenance, method)."""
    out: list[tuple[Any, ...]] = [("Ts",)]
    stack: list[tuple[tuple[Any, ...], Any]] = []
    for section, keys in _VALIDATED.items():
        items = doc[section] if isinstance(doc[section], list) else [doc[section]]
        for i, obj in enumerate(items):
            base = (section, i) if isinstance(doc[section], list) else (section,)
            stack += [((*base, k), obj[k]) for k in keys if k in obj]
    while stack:
        path, node = stack.pop()
        if isinstance(node, list):
            stack += [((*path, j), v) for j, v in enumerate(node)]
        elif isinstance(node, (int, float)) and not isinstance(node, bool):
            out.append(path)
    return out


def _set(doc: Any, path: tuple[Any, ...], value: float) -> None:
    for k in path[:-1]:
        doc = doc[k]
    doc[path[-1]] = value


def _field_named(path: tuple[Any, ...]) -> str:
    """The name a refusal must hold: the matrix or field that holds the entry (``Bu``, ``threshold``, ``Ts``)."""
    return next(str(k) for k in reversed(path) if isinstance(k, str))


def _locator(path: tuple[Any, ...]) -> str:
    """What a refusal of a tampered entry names: its generator or evaluator (by index), else its field."""
    return f"{path[0]}[{path[1]}]" if path[0] in ("generators", "evaluators") else _field_named(path)


def _norm(a: np.ndarray) -> Any:
    return np.sqrt(np.sum(np.asarray(a, dtype=_L) ** 2))


def _assert_consistent(gf: GainFile) -> None:
    """Every relation the reader checks, recomputed in extended precision: it holds, at finite values."""
    for k, a in gf.plant.items():
        assert np.all(np.abs(a) <= MAX_MAGNITUDE), k
    for g in gf.generators:
        for k in ("Ar", "Bu", "By", "Cr", "Du", "Dy", "Xu", "Xy"):
            assert np.all(np.abs(getattr(g, k)) <= MAX_MAGNITUDE), (g.name, k)
        if g.n_state:
            assert float(np.max(np.abs(np.linalg.eigvals(g.Ar)))) < 1.0, g.name
            lhs = np.eye(g.n_state, dtype=_L) - g.Ar.astype(_L)
            for xk, bk in (("Xu", "Bu"), ("Xy", "By")):
                x, b = getattr(g, xk).astype(_L), getattr(g, bk).astype(_L)
                res, bound = _norm(lhs @ x - b), 1e-8 * (_norm(b) + _norm(g.Ar) * _norm(x) + _L(1e-300))
                assert np.isfinite(float(res)) and np.isfinite(float(bound)) and res <= bound, (g.name, xk, float(res), float(bound))
    for e in gf.evaluators:
        assert 0 < e.threshold <= MAX_MAGNITUDE and np.all(np.abs(e.W) <= MAX_MAGNITUDE) and np.all(np.abs(e.Sigma_r) <= MAX_MAGNITUDE)
        w, s = e.W.astype(_L), e.Sigma_r.astype(_L)
        gap = _norm(w @ s @ w - w) / _norm(w)
        assert np.isfinite(float(gap)) and gap <= 1e-6, float(gap)


def _mutate(rng: np.random.Generator, base: dict[str, Any]) -> tuple[dict[str, Any], list[tuple[Any, ...]], list[float]]:
    doc = copy.deepcopy(base)
    paths = _numeric_paths(doc)
    picked = [paths[int(i)] for i in rng.choice(len(paths), size=int(rng.integers(1, 4)), replace=False)]
    values = [float(VALUES[int(rng.integers(len(VALUES)))]) for _ in picked]
    for p, v in zip(picked, values, strict=True):
        _set(doc, p, v)
    return doc, picked, values


def test_every_committed_gain_file_is_read() -> None:
    """Nothing a design writes is refused: the committed reports' gain files (every kind) are within the bound."""
    assert len(GAINS) >= 30
    for p in GAINS:
        read_gain_file(p)


@pytest.mark.parametrize("matrix", ["Bu", "By", "Xu", "Xy"])
@pytest.mark.parametrize("value", [1e308, -1e308])
def test_an_overflowing_entry_with_an_inconsistent_equilibrium_map_is_refused(tmp_path: Path, matrix: str, value: float) -> None:
    doc = json.loads(LINEAR[0].read_text(encoding="utf-8"))
    g = doc["generators"][0]
    g[matrix][0][0] = value
    other = {"Bu": "Xu", "By": "Xy", "Xu": "Xy", "Xy": "Xu"}[matrix]
    g[other][0][0] += 1.0  # an inconsistent map beside it
    with pytest.raises(GainFileError, match=rf"generators\[0\]: {matrix}\[0\]\[0\] is {re.escape(repr(value))}; .*at most 1e\+150"):
        read_gain_file(_write(tmp_path, doc))


@pytest.mark.parametrize("matrix", ["Bu", "By", "Xu", "Xy"])
def test_an_entry_at_the_bound_still_meets_the_equilibrium_check(tmp_path: Path, matrix: str) -> None:
    """Within the bound the check stays finite, so an inconsistent map is refused by the check itself."""
    doc = json.loads(LINEAR[0].read_text(encoding="utf-8"))
    doc["generators"][0][matrix][0][0] = MAX_MAGNITUDE
    eq = "Xu" if matrix in ("Bu", "Xu") else "Xy"
    with pytest.raises(GainFileError, match=rf"generators\[0\] \(\w+\)\.{eq} is not \(I − Ar\)⁻¹ B[uy] \(residual [0-9.e+]+, allowed [0-9.e+]+\)"):
        read_gain_file(_write(tmp_path, doc))


def test_a_consistent_file_scaled_to_the_bound_is_read(tmp_path: Path) -> None:
    """A generator whose Bu and Xu are both scaled up to the bound is consistent and read: the bound is no consistency rule."""
    doc = json.loads(LINEAR[0].read_text(encoding="utf-8"))
    g = doc["generators"][0]
    k = MAX_MAGNITUDE / max(abs(v) for row in g["Bu"] + g["Xu"] for v in row)
    for key in ("Bu", "Xu"):
        g[key] = [[v * k for v in row] for row in g[key]]
    _assert_consistent(read_gain_file(_write(tmp_path, doc)))


@pytest.mark.parametrize(("path", "value"), [(("Ts",), 1e200), (("evaluators", 0, "threshold"), 1e308), (("evaluators", 0, "W", 0, 0), -1e200)])
def test_other_huge_numbers_are_refused_by_name(tmp_path: Path, path: tuple[Any, ...], value: float) -> None:
    doc = json.loads(LINEAR[0].read_text(encoding="utf-8"))
    _set(doc, path, value)
    with pytest.raises(GainFileError, match=rf"{_field_named(path)}(\[0\]\[0\])? is {re.escape(repr(value))}; a gain file's numbers must be finite and at most"):
        read_gain_file(_write(tmp_path, doc))


def test_huge_entries_are_refused_by_name_or_consistent(tmp_path: Path) -> None:
    """The seeded fuzzer: each tampered file is refused naming a tampered field, or every relation holds."""
    bases = [json.loads(p.read_text(encoding="utf-8")) for p in LINEAR]
    rng = np.random.default_rng(SEED)
    outcomes = {"refused": 0, "accepted": 0}
    for i in range(MUTATIONS):
        doc, picked, values = _mutate(rng, bases[i % len(bases)])
        try:
            gf = read_gain_file(_write(tmp_path, doc))
        except GainFileError as exc:
            msg = str(exc)
            assert "\n" not in msg, msg
            # the refusal names a tampered field: the bound's refusal, or a relation on the tampered generator,
            # evaluator or field (a generator's or an evaluator's index, the plant matrix, Ts, init_state)
            assert any(_locator(p) in msg for p in picked), (picked, values, msg)
            if all(abs(v) > MAX_MAGNITUDE for v in values):
                assert "at most 1e+150" in msg and any(f"{_field_named(p)}[" in msg or f"{_field_named(p)} is" in msg for p in picked), msg
            outcomes["refused"] += 1
            continue
        assert all(abs(v) <= MAX_MAGNITUDE for v in values), (picked, values)
        _assert_consistent(gf)
        outcomes["accepted"] += 1
    assert outcomes["refused"] > MUTATIONS // 2 and outcomes["accepted"] > 0, outcomes
