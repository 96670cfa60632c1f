"""Seeded fuzzing of a NAFDF gain file: whatever a file holds, reading it, building its step and
generating its C either succeed (and the step runs finite) or end in one fdisyn error line.

A valid ship gain file is first swept — every field the NAFDF reader reads replaced in turn by a
string, null, −1, 1e308 and an empty list — then mutated at random: byte flips in the
JSON text, deleted fields, values of the wrong type, extreme numbers, lists of the wrong length,
corrupted model programs, small edits of numbers (consistent-looking but wrong files), and programs
edited with the readable expressions removed (valid, different models, which must build and run). Everything that reaches CasADi runs in a
child process, so a crash inside native code is reported as a failure naming the mutation instead
of killing the test session; NumPy's RuntimeWarnings are errors there, so a silent overflow on
the way is reported too.
"""

from __future__ import annotations

import copy
import json
import subprocess
import sys
import tempfile
import traceback
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
SEED = 20240601
MUTATIONS = 100
_POOL: list[Any] = ["x", "", -1, 0, 1, 1.5, None, [], {}, True, 1e308, -1e308, 1e-320, [[1.0]], 10**30, "nan", [None], {"a": 1}]
_NUMBERS: list[Any] = [0, 0.0, -0.0, 1e308, -1e308, 1e-308, 10**20, -(10**20), 3, -3, 0.5, 2**53 + 1]


def _paths(doc: Any) -> list[tuple[Any, ...]]:
    """Every node's path, walked with a stack (no recursion)."""
    out: list[tuple[Any, ...]] = []
    stack: list[tuple[tuple[Any, ...], Any]] = [((), doc)]
    while stack:
        path, node = stack.pop()
        if path:
            out.append(path)
        if isinstance(node, dict):
            stack.extend(((*path, k), v) for k, v in node.items())
        elif isinstance(node, list):
            stack.extend(((*path, i), v) for i, v in enumerate(node))
    return out


def _get(doc: Any, path: tuple[Any, ...]) -> Any:
    for k in path:
        doc = doc[k]
    return doc


def _pick(rng: np.random.Generator, paths: list[tuple[Any, ...]]) -> tuple[Any, ...]:
    """A node, four times in five inside the NAFDF payload (the part this fuzzer is about)."""
    inner = [p for p in paths if p[:2] == ("extensions", "nafdf")]
    pool = inner if inner and rng.random() < 0.8 else paths
    return pool[int(rng.integers(len(pool)))]


def mutate(base: dict, text: bytes, rng: np.random.Generator) -> tuple[str, bytes]:
    """One seeded mutation of the gain file: its description and the bytes to write."""
    kind = int(rng.integers(9))
    if kind == 0:  # byte flips in the JSON text, mostly inside the payload
        raw = bytearray(text)
        start = text.find(b'"nafdf": {')
        flips = []
        for _ in range(int(rng.integers(1, 4))):
            pos = int(rng.integers(start, len(raw))) if start >= 0 and rng.random() < 0.8 else int(rng.integers(len(raw)))
            val = int(rng.integers(0, 256)) if rng.random() < 0.3 else int(rng.choice(list(b'0123456789.-+eE",:[]{} nulltrue')))
            raw[pos] = val
            flips.append((pos, val))
        return f"byte flips {flips}", bytes(raw)
    doc = copy.deepcopy(base)
    paths = _paths(doc)
    if kind == 8:  # a valid but different model: edit a program constant, drop the readable expressions
        fun = "f" if rng.random() < 0.7 else "h"
        prog = doc["extensions"]["nafdf"]["plant"][fun]
        consts = [i for i, op in enumerate(prog["ops"]) if op[0] == "const"]
        doc["extensions"]["nafdf"]["plant"]["expressions"] = None
        if consts:
            i = consts[int(rng.integers(len(consts)))]
            prog["ops"][i][1] = float(rng.choice([0.0, 0.05, 0.1, 0.3, -0.2, 1.0]))
            desc = f"{fun}.ops[{i}] const → {prog['ops'][i][1]}, expressions removed"
        else:
            desc = f"expressions removed ({fun} has no constant)"
        return desc, json.dumps(doc).encode()
    if kind == 7:  # corrupted model program
        fun = "f" if rng.random() < 0.7 else "h"
        prog = doc["extensions"]["nafdf"]["plant"][fun]
        i = int(rng.integers(len(prog["ops"])))
        choice = int(rng.integers(5))
        if choice == 0:
            prog["ops"][i][0] = str(rng.choice(["add", "mul", "sin", "log", "fabs", "call", "input", "const", "pow", "erfinv"]))
        elif choice == 1 and len(prog["ops"][i]) > 1:
            prog["ops"][i][int(rng.integers(1, len(prog["ops"][i])))] = int(rng.choice([-1, 0, i, i + 1, 10**9]))
        elif choice == 2:
            prog["ops"][i] = copy.deepcopy(_POOL[int(rng.integers(len(_POOL)))])
        elif choice == 3:
            prog["out"] = [int(rng.integers(-2, len(prog["ops"]) + 2)) for _ in prog["out"]]
        else:
            prog["ops"].insert(i, ["const", float(rng.choice([1e308, -1e308, 0.0, 2.0]))])
        return f"{fun} program: op {i}, change {choice}", json.dumps(doc).encode()
    path = _pick(rng, paths)
    parent, key = _get(doc, path[:-1]), path[-1]
    if kind == 1:  # deleted field or element
        del parent[key]
        desc = f"delete {path}"
    elif kind == 2:  # a value of another type
        parent[key] = copy.deepcopy(_POOL[int(rng.integers(len(_POOL)))])
        desc = f"{path} → {parent[key]!r}"
    elif kind == 3:  # an extreme number in place of a number
        nums = [p for p in paths if isinstance(_get(doc, p), (int, float)) and not isinstance(_get(doc, p), bool)]
        path = _pick(rng, nums)
        parent, key = _get(doc, path[:-1]), path[-1]
        parent[key] = _NUMBERS[int(rng.integers(len(_NUMBERS)))]
        desc = f"{path} → {parent[key]!r}"
    elif kind == 4:  # a list one longer or one shorter
        lists = [p for p in paths if isinstance(_get(doc, p), list) and _get(doc, p)]
        path = _pick(rng, lists)
        node = _get(doc, path)
        if rng.random() < 0.5:
            node.append(copy.deepcopy(node[-1]))
            desc = f"{path} one longer"
        else:
            node.pop(int(rng.integers(len(node))))
            desc = f"{path} one shorter"
    elif kind == 5:  # a small edit of a number: a file that looks consistent but is not
        nums = [p for p in paths if isinstance(_get(doc, p), float)]
        path = _pick(rng, nums)
        parent, key = _get(doc, path[:-1]), path[-1]
        parent[key] = parent[key] * (1.0 + 1e-3) + 1e-9
        desc = f"{path} nudged"
    else:  # a field renamed (unknown + missing)
        if isinstance(parent, dict):
            parent[f"{key}_x"] = parent.pop(key)
            desc = f"rename {path}"
        else:
            parent[key] = {"unexpected": parent[key]}
            desc = f"wrap {path}"
    return desc, json.dumps(doc).encode()


_SWEEP_VALUES: list[Any] = ["x", None, -1, 1e308, []]


def sweep(base: dict) -> list[tuple[str, bytes]]:
    """Every field the NAFDF reader reads (of a list, its first element) replaced in turn by each
    value of :data:`_SWEEP_VALUES`. The stored certificate's checks and info, like the provenance, are
    informational (the design is re-certified on reading), so only ``certificate.passed`` is swept there."""
    out = []
    for path in _paths(base):
        if path[0] == "provenance" or (path[0] == "certificate" and path[1:] != ("passed",)):
            continue
        if path[:3] == ("extensions", "nafdf", "certificate") and path[3:] != ("passed",):
            continue
        parent = _get(base, path[:-1])
        if isinstance(parent, list) and path[-1] != 0:
            continue
        for value in _SWEEP_VALUES:
            doc = copy.deepcopy(base)
            _get(doc, path[:-1])[path[-1]] = copy.deepcopy(value)
            out.append((f"sweep {path} → {value!r}", json.dumps(doc).encode()))
    return out


def run_mutations(seed: int, count: int, workdir: str) -> None:
    """The child: build a valid gain file, then for each mutation report start and outcome as JSON lines."""
    from fdisyn.codegen.library import generate_sources
    from fdisyn.codegen.step import step_function
    from fdisyn.problems import ship_propulsion as sp
    from fdisyn.runtime.errors import FdisynError
    from fdisyn.runtime.gainfile import read_gain_file, write_gain_file
    from fdisyn.synthesis.nafdf.payload import nafdf_gain_file

    work = Path(workdir)
    base_path = write_gain_file(nafdf_gain_file(sp.design(), problem="ship_propulsion"), work / "base.json")
    text = base_path.read_bytes()
    base = json.loads(text)
    rng = np.random.default_rng(seed)
    run = sp.PROBLEM.run(sp.fault_scenario("fault_free", length=20), [1])
    u, y = run.U[0], run.Y[0]
    cases = [("unchanged", text), *sweep(base)]
    for i in range(len(cases) + count):
        desc, data = cases[i] if i < len(cases) else mutate(base, text, rng)
        print(json.dumps({"i": i, "start": desc}), flush=True)
        path = work / "gains.json"
        path.write_bytes(data)
        rec: dict[str, Any] = {"i": i}
        try:
            gf = read_gain_file(path)
            fn = step_function(gf)
            generate_sources(gf, work / "c", step=fn)
            state = np.array(gf.step.init_state, dtype=float)
            finite = True
            for k in range(u.shape[0]):
                out = fn(state, u[k, : gf.step.nu], y[k, : gf.step.ny])
                vals = [np.array(o, dtype=float) for o in out]
                finite = finite and all(np.all(np.isfinite(v)) for v in vals)
                state = vals[0].reshape(-1)
            rec.update(outcome="ok" if finite else "bad", message="" if finite else "the step emitted a non-finite value")
        except FdisynError as exc:
            rec.update(outcome="refused", type=type(exc).__name__, message=str(exc))
        except Exception as exc:  # noqa: BLE001 - exactly what the fuzzer looks for
            rec.update(outcome="bad", type=type(exc).__name__, message="".join(traceback.format_exception(exc))[-1500:])
        print(json.dumps(rec), flush=True)


def test_mutated_nafdf_gain_files_never_crash_or_raise_anything_but_one_fdisyn_line() -> None:
    with tempfile.TemporaryDirectory() as work:
        proc = subprocess.run(
            # RuntimeWarning as an error: a silent NumPy overflow on the way is a finding too
            [sys.executable, "-W", "error::RuntimeWarning", "-c",
             f"from tests.design.test_nafdf_payload_fuzz import run_mutations; run_mutations({SEED}, {MUTATIONS}, {work!r})"],
            cwd=ROOT, capture_output=True, text=True, timeout=600, check=False,
        )
    started: dict[int, str] = {}
    outcomes: dict[int, dict[str, Any]] = {}
    for line in proc.stdout.splitlines():
        rec = json.loads(line)
        if "start" in rec:
            started[rec["i"]] = rec["start"]
        else:
            outcomes[rec["i"]] = rec
    crashed = [f"{i}: {d}" for i, d in started.items() if i not in outcomes]
    assert proc.returncode == 0 and not crashed, f"child ended with {proc.returncode} during {crashed}: {proc.stderr[-2000:]}"
    assert len(outcomes) > MUTATIONS and outcomes[0]["outcome"] == "ok", outcomes.get(0)
    bad = [f"{i} ({started[i]}): {r['message']}" for i, r in outcomes.items() if r["outcome"] == "bad"]
    assert not bad, "\n\n".join(bad)
    multi = [f"{i} ({started[i]}): {r['message']!r}" for i, r in outcomes.items() if r["outcome"] == "refused" and ("\n" in r["message"] or not r["message"])]
    assert not multi, "\n".join(multi)
    kinds = {r["outcome"] for r in outcomes.values()}
    refused = sum(r["outcome"] == "refused" for r in outcomes.values())
    ok = sum(r["outcome"] == "ok" for r in outcomes.values())
    # not vacuous: most mutations are refused, and some mutated files (other valid models) build and run
    assert kinds == {"ok", "refused"} and refused >= MUTATIONS // 2 and ok >= 5, (refused, ok)


# --------------------------------------------------------------------------- huge numbers
_SHIP = ROOT / "reports" / "ship_propulsion" / "gains" / "ship_propulsion_nafdf.json"
_BOUND_SEED = 20240626
_BOUND_MUTATIONS = 60
_HUGE: list[float] = [1e308, -1e308, 1e200, -1e200, 1e150 * (1 + 1e-12), 1e150, -1e150, 0.999e150, 1e100]


def _payload_numbers(doc: dict[str, Any]) -> list[tuple[Any, ...]]:
    """Paths to the numbers of the payload the reader validates (settings, noise covariances, θ, tables, state)."""
    payload = doc["extensions"]["nafdf"]
    roots = [("settings",), ("plant", "theta_nominal"), ("plant", "Q1"), ("plant", "Q2"), ("plant", "Ts"), ("detector_thresholds",), ("init_state",), ("thresholds",)]
    out = []
    for root in roots:
        if root[0] not in payload:
            continue
        out += [("extensions", "nafdf", *root, *p) for p in _paths(_get(payload, root))] or [("extensions", "nafdf", *root)]
    return [p for p in out if isinstance(_get(doc, p), (int, float)) and not isinstance(_get(doc, p), bool)]


def test_huge_payload_numbers_are_refused_by_name_or_consistent(tmp_path: Path) -> None:
    """±1e308, ±1e200 and values about the gain file's magnitude bound in the ship's payload: refused naming the
    field, or the payload's relations (its threshold table, initial state and exported thresholds against the
    settings) hold at finite values. In-process: only the reader and the design's re-certification run."""
    import warnings

    from fdisyn.runtime.errors import GainFileError
    from fdisyn.runtime.gainfile import read_gain_file
    from fdisyn.runtime.schema import MAX_MAGNITUDE
    from fdisyn.synthesis.nafdf.design import _init_state, detector_thresholds
    from fdisyn.synthesis.nafdf.payload import nafdf_from_gain_file

    base = json.loads(_SHIP.read_text(encoding="utf-8"))
    paths = _payload_numbers(base)
    rng = np.random.default_rng(_BOUND_SEED)
    outcomes = {"refused": 0, "accepted": 0}
    for _ in range(_BOUND_MUTATIONS):
        doc = copy.deepcopy(base)
        path, value = paths[int(rng.integers(len(paths)))], float(rng.choice(_HUGE))
        _get(doc, path[:-1])[path[-1]] = value
        (tmp_path / "gains.json").write_text(json.dumps(doc), encoding="utf-8")
        with warnings.catch_warnings():
            warnings.simplefilter("error", RuntimeWarning)  # a silent overflow on the way is a finding
            try:
                gf = read_gain_file(tmp_path / "gains.json")
                design = nafdf_from_gain_file(gf)
            except GainFileError as exc:
                msg = str(exc)
                field = next(str(k) for k in reversed(path) if isinstance(k, str))
                assert "\n" not in msg and field in msg, (path, value, msg)
                if abs(value) > MAX_MAGNITUDE:
                    assert "at most 1e+150" in msg or "must be" in msg, (path, value, msg)
                outcomes["refused"] += 1
                continue
        assert abs(value) <= MAX_MAGNITUDE, (path, value)
        truth = detector_thresholds(design.plant, design.settings)
        assert np.all(np.isfinite(truth)) and np.allclose(design.thresholds, truth, rtol=1e-9, atol=0.0)
        init = _init_state(design.plant, design.settings, design.layout)
        assert np.all(np.abs(init) <= MAX_MAGNITUDE) and np.array_equal(gf.step.init_state, init)
        assert np.all(np.isfinite(gf.thresholds[np.isfinite(gf.thresholds)]))
        outcomes["accepted"] += 1
    assert outcomes["refused"] > _BOUND_MUTATIONS // 2 and outcomes["accepted"] > 0, outcomes
