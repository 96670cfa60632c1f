"""Huge numbers in a Beard filter's payload: refused by name, or every relation holds at finite values.

Bases are the satellite's committed gain files (``reports/satellite_pitch/gains``: no design runs here).
A seeded fuzzer sets numbers of ``extensions.beard_fdf`` to ±1e308, ±1e200, values just outside, at and
just inside :data:`~fdisyn.runtime.schema.MAX_MAGNITUDE`; each tampered file is either refused with a
:class:`GainFileError` naming the payload field, or the reader's relations — ``A − L C`` Schur stable,
the equilibrium maps, orthonormal axes — hold when recomputed in extended precision.
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
from fdisyn.runtime.gainfile import read_gain_file
from fdisyn.runtime.schema import MAX_MAGNITUDE
from fdisyn.synthesis.beard_fdf.payload import BeardFilter, beard_from_gain_file

ROOT = Path(__file__).resolve().parents[2]
BASES = [ROOT / "reports" / "satellite_pitch" / "gains" / f"satellite_pitch_{v}.json" for v in ("optimised", "plain")]
SEED = 20240625
MUTATIONS = 200
EDGE = MAX_MAGNITUDE * (1 + 1e-12)
VALUES = (1e308, -1e308, 1e200, -1e200, EDGE, -EDGE, MAX_MAGNITUDE, -MAX_MAGNITUDE, 0.999 * MAX_MAGNITUDE, 1e100, 1e20)
NUMERIC = ("A", "B", "C", "D", "L", "Xu", "Xy", "axes", "Y_th", "h", "explicit_level", "rho")
_L = np.longdouble


def _write(tmp_path: Path, doc: Any) -> Path:
    p = tmp_path / "gains.json"
    p.write_text(json.dumps(doc), encoding="utf-8")
    return p


def _paths(payload: dict[str, Any]) -> list[tuple[Any, ...]]:
    out: list[tuple[Any, ...]] = []
    stack: list[tuple[tuple[Any, ...], Any]] = [((k,), payload[k]) for k in NUMERIC]
    while stack:
        path, node = stack.pop()
        if isinstance(node, list):
            stack += [((*path, i), v) for i, v in enumerate(node)]
        elif isinstance(node, (int, float)) and not isinstance(node, bool):
            out.append(path)
    return out


def _norm(a: Any) -> Any:
    return np.sqrt(np.sum(np.asarray(a, dtype=_L) ** 2))


def _assert_consistent(flt: BeardFilter, payload: dict[str, Any]) -> None:
    """The reader's relations, recomputed in extended precision on the file's own numbers."""
    mats = {k: np.asarray(payload[k], dtype=float) for k in ("A", "B", "C", "D", "L", "Xu", "Xy")}
    for k, a in mats.items():
        assert np.all(np.abs(a) <= MAX_MAGNITUDE), k
    a, b, c, d, gain = (mats[k].astype(_L) for k in ("A", "B", "C", "D", "L"))
    g = a - gain @ c
    assert np.all(np.isfinite(g.astype(float))) and float(np.max(np.abs(np.linalg.eigvals(g.astype(float))))) < 1.0
    lhs = np.eye(flt.n, dtype=_L) - g
    for key, rhs in (("Xu", b - gain @ d), ("Xy", gain)):
        x = mats[key].astype(_L)
        res, scale = _norm(lhs @ x - rhs), _norm(rhs) + _norm(lhs) * _norm(x)
        assert np.isfinite(float(res)) and np.isfinite(float(scale)) and res <= 1e-6 * scale + 1e-300, (key, float(res), float(scale))
    for ax in flt.axes:
        u = ax.astype(_L)
        assert float(np.max(np.abs(u.T @ u - np.eye(u.shape[1], dtype=_L)))) <= 1e-9
    assert 0 < flt.h <= MAX_MAGNITUDE and 0 < flt.explicit_level <= MAX_MAGNITUDE
    assert flt.rho is None or 1 < flt.rho <= MAX_MAGNITUDE


@pytest.mark.parametrize("entry", [(0, 0), (2, 0), (3, 1)])
def test_an_overflowing_input_matrix_is_refused_by_name(tmp_path: Path, entry: tuple[int, int]) -> None:
    """``B = 1e308`` once made the equilibrium map's check ``gap ≤ 1e-8·inf`` and was accepted."""
    doc = json.loads(BASES[0].read_text(encoding="utf-8"))
    doc["extensions"]["beard_fdf"]["B"][entry[0]][entry[1]] = 1e308
    with pytest.raises(GainFileError, match=re.escape(f"extensions.beard_fdf.B[{entry[0]}][{entry[1]}] is 1e+308; a gain file's numbers must be finite and at most 1e+150")):
        beard_from_gain_file(read_gain_file(_write(tmp_path, doc)))


@pytest.mark.parametrize(
    ("value", "message"),
    [
        (1e148, r"extensions\.beard_fdf\.Xu must be the equilibrium map .* found it [0-9.e+]+ away"),
        (MAX_MAGNITUDE, r"extensions\.beard_fdf\.Xu: A B C D L give an equilibrium map with entries up to [0-9.e+]+, beyond 1e\+150"),
    ],
)
def test_an_input_matrix_within_the_bound_meets_the_equilibrium_check(tmp_path: Path, value: float, message: str) -> None:
    """Within the bound the check stays finite: the stored Xu no longer matches and is refused by name."""
    doc = json.loads(BASES[0].read_text(encoding="utf-8"))
    doc["extensions"]["beard_fdf"]["B"][2][0] = value
    with pytest.raises(GainFileError, match=message):
        beard_from_gain_file(read_gain_file(_write(tmp_path, doc)))


def test_a_nearly_singular_filter_is_refused_not_overflowed(tmp_path: Path) -> None:
    """``A − L C`` with an eigenvalue at 1 − 1e-17 is Schur stable to the float; its equilibrium solve
    overflows (or is singular) and is refused, not compared with ``inf``."""
    doc = json.loads(BASES[1].read_text(encoding="utf-8"))
    pl = doc["extensions"]["beard_fdf"]
    n = len(pl["A"])
    pl["L"] = [[0.0] * len(pl["L"][0]) for _ in range(n)]
    pl["A"] = (np.eye(n) * (1 - 1e-16)).tolist()
    pl["B"] = [[MAX_MAGNITUDE] * len(pl["B"][0]) for _ in range(n)]
    with pytest.raises(GainFileError, match=r"extensions\.beard_fdf\.(Xu: A B C D L give an equilibrium map with entries up to|L must make A − L C Schur stable)"):
        beard_from_gain_file(read_gain_file(_write(tmp_path, doc)))


def test_huge_payload_numbers_are_refused_by_name_or_consistent(tmp_path: Path) -> None:
    bases = [json.loads(p.read_text(encoding="utf-8")) for p in BASES]
    rng = np.random.default_rng(SEED)
    outcomes = {"bound": 0, "relation": 0, "accepted": 0}
    for i in range(MUTATIONS):
        doc = copy.deepcopy(bases[i % len(bases)])
        payload = doc["extensions"]["beard_fdf"]
        # the scalars a third of the time (they are few among the matrices' entries), the thresholds kept coherent
        paths = _paths(payload) if rng.random() < 2 / 3 else [("h",), ("explicit_level",)]
        picked = [paths[int(j)] for j in rng.choice(len(paths), size=int(rng.integers(1, 3)), replace=False)]
        values = [float(VALUES[int(rng.integers(len(VALUES)))]) for _ in picked]
        for path, v in zip(picked, values, strict=True):
            node = payload
            for k in path[:-1]:
                node = node[k]
            node[path[-1]] = v
        payload["thresholds"][0] = payload["h"]
        try:
            flt = beard_from_gain_file(read_gain_file(_write(tmp_path, doc)))
        except GainFileError as exc:
            msg = str(exc)
            assert "\n" not in msg and "beard_fdf" in msg, msg
            # h is mirrored in the generic thresholds, which the common reader checks first
            named = [f".{p[0]}[" for p in picked] + [f".{p[0]} " for p in picked] + ([".thresholds[0]"] if ("h",) in picked else [])
            if all(abs(v) > MAX_MAGNITUDE for v in values):  # the bound's refusal, or a field's own domain (Y_th)
                assert any(n in msg for n in named), (picked, values, msg)
            else:  # or a relation the tampered entries broke
                assert any(n in msg for n in named) or any(r in msg for r in (".Xu", ".Xy", "Schur")), (picked, values, msg)
            outcomes["bound" if "at most 1e+150" in msg else "relation"] += 1
            continue
        assert all(abs(v) <= MAX_MAGNITUDE for v in values), (picked, values)
        _assert_consistent(flt, payload)
        outcomes["accepted"] += 1
    assert min(outcomes.values()) > 0 and outcomes["bound"] > MUTATIONS // 3, outcomes
