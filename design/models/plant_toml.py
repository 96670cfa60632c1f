"""Plants written as TOML plant files: the text ``LinearPlant.to_toml`` and ``NonlinearPlant.to_toml`` return.

The plant file is the one format a plant has outside Python (``design/examples/PLANT_FILES.md``); a plant written
here and read back by ``fdisyn.simulation.plant_file`` is the same plant: every float is written as Python's
shortest repr, which reads back as the same double, and the names, labels and units are copied as given.
Only what a plant file can hold is written: numbers, strings, booleans, lists and tables of them.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from fdisyn.runtime.errors import ArgumentError

__all__ = ["toml_text", "linear_tables", "nonlinear_tables", "plant_file_text"]

_BARE_KEY = re.compile(r"[A-Za-z0-9_-]+")


def _key(k: str) -> str:
    return k if _BARE_KEY.fullmatch(k) else json.dumps(k, ensure_ascii=False)


def _value(v: Any, where: str) -> str:
    """One TOML value (inline): strings in JSON's escapes (a subset of TOML's basic strings), floats by repr."""
    if isinstance(v, (bool, np.bool_)):
        return "true" if v else "false"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        x = float(v)
        if not math.isfinite(x):
            raise ArgumentError(f"{where} is {x!r}; a plant file holds finite numbers only")
        return repr(x)
    if isinstance(v, str):  # JSON's escapes are TOML's; DEL, which JSON leaves raw, TOML wants escaped
        return json.dumps(v, ensure_ascii=False).replace("\x7f", "\\u007f")
    if isinstance(v, np.ndarray):
        return _value(v.tolist(), where)
    if isinstance(v, Mapping):
        return "{ " + ", ".join(f"{_key(str(k))} = {_value(x, f'{where}.{k}')}" for k, x in v.items()) + " }" if v else "{}"
    if isinstance(v, Sequence):
        return "[" + ", ".join(_value(x, f"{where}[{i}]") for i, x in enumerate(v)) + "]"
    raise ArgumentError(f"{where} is a {type(v).__name__}; a plant file holds numbers, strings, lists and tables")


def toml_text(doc: Mapping[str, Any]) -> str:
    """``doc`` as TOML: top-level values, then one ``[table]`` per mapping and ``[[array]]`` per list of mappings.

    Parameters
    ----------
    doc : Mapping
        A plant-file document (what ``tomllib.loads`` of the text returns).

    Returns
    -------
    str
        The TOML text.

    Raises
    ------
    ArgumentError
        A value a plant file cannot hold (a non-finite number, an object that is no number, string, list or table).
    """
    head, tables = [], []
    for k, v in doc.items():
        if isinstance(v, Mapping):
            body = "".join(f"{_key(str(kk))} = {_value(vv, f'[{k}].{kk}')}\n" for kk, vv in v.items())
            tables.append(f"[{_key(k)}]\n{body}")
        elif isinstance(v, list) and v and all(isinstance(x, Mapping) for x in v):
            for i, x in enumerate(v):
                body = "".join(f"{_key(str(kk))} = {_value(vv, f'[[{k}]][{i}].{kk}')}\n" for kk, vv in x.items())
                tables.append(f"[[{_key(k)}]]\n{body}")
        else:
            head.append(f"{_key(k)} = {_value(v, k)}\n")
    return "".join(head) + "".join("\n" + t for t in tables)


def _named(names: Mapping[str, str], signals: Sequence[str]) -> dict[str, str]:
    return {s: names[s] for s in signals if s in names}


def _signals(plant: Any, groups: Mapping[str, Sequence[str]]) -> dict[str, Any]:
    every = [s for g in groups.values() for s in g]
    out: dict[str, Any] = {k: list(v) for k, v in groups.items() if len(v)}
    units = _named(getattr(plant, "units", {}) or {}, every)
    labels = _named(getattr(plant, "labels", {}) or {}, every)
    if units:
        out["units"] = units
    if labels:
        out["labels"] = labels
    return out


def linear_tables(plant: Any, *, Ts: float | None = None) -> dict[str, Any]:
    """The ``[signals]`` and ``[model]`` tables of a :class:`~fdisyn.models.linear.LinearPlant`.

    A plant in scaled states (:meth:`~fdisyn.models.linear.LinearPlant.scaled`) is written in its original states
    with ``state_scale``, which the reader applies again (its matrices agree to round-off). The process noise is
    written as ``Q_intensity`` (continuous) or ``Q_sample`` (discrete), so the file says which it is.

    Parameters
    ----------
    plant : LinearPlant
        The plant.
    Ts : float, optional
        The diagnoser's sample time, required for a continuous plant (the file samples it); a discrete plant's
        own ``Ts`` when not given (given, it must be that one).

    Returns
    -------
    dict
        ``{"signals": …, "model": …}``.

    Raises
    ------
    ArgumentError
        A continuous plant without ``Ts``, or a discrete one with another ``Ts``.
    """
    from fdisyn.models.sampling import check_sample_time

    if plant.Ts is None:
        if Ts is None:
            raise ArgumentError("a continuous plant's file needs the sample time it is diagnosed at: give Ts (s), e.g. to_toml(Ts=0.01)")
        ts, time = check_sample_time(Ts), "continuous"
    else:
        if Ts is not None and check_sample_time(Ts) != plant.Ts:
            raise ArgumentError(f"Ts = {Ts!r} differs from the discrete plant's own Ts = {plant.Ts!r}; leave Ts out")
        ts, time = plant.Ts, "discrete"
    mats = {k: np.asarray(getattr(plant, k), dtype=float) for k in ("A", "B", "C", "D", "E", "Fx", "Dd", "Df", "Q", "R")}
    if plant.state_scale is not None:  # back to the original states x = S x̃
        s = np.asarray(plant.state_scale, dtype=float)
        si = 1.0 / s
        mats.update(A=s[:, None] * mats["A"] * si[None, :], B=s[:, None] * mats["B"], C=mats["C"] * si[None, :],
                    E=s[:, None] * mats["E"], Fx=s[:, None] * mats["Fx"], Q=s[:, None] * mats["Q"] * s[None, :])  # fmt: skip
    model: dict[str, Any] = {"time": time, "Ts": float(ts)}
    for k in ("A", "B", "C", "D", "E", "Fx", "Dd", "Df"):
        if mats[k].size and (k in ("A", "C") or np.any(mats[k] != 0)):
            model[k] = mats[k].tolist()
    model["Q_intensity" if time == "continuous" else "Q_sample"] = mats["Q"].tolist()
    model["R"] = mats["R"].tolist()
    if plant.state_scale is not None:
        model["state_scale"] = [float(x) for x in plant.state_scale]
    groups = {"states": plant.states, "inputs": plant.inputs, "unknown_inputs": plant.unknown_inputs, "outputs": plant.outputs,
              "component_faults": plant.component_faults}  # fmt: skip
    return {"signals": _signals(plant, groups), "model": model}


def nonlinear_tables(plant: Any) -> dict[str, Any]:
    """The ``[signals]`` and ``[model]`` tables of a :class:`~fdisyn.models.nonlinear.NonlinearPlant` built from expressions.

    Parameters
    ----------
    plant : NonlinearPlant
        A plant from :meth:`~fdisyn.models.nonlinear.NonlinearPlant.from_expressions` (or a plant file).

    Returns
    -------
    dict
        ``{"signals": …, "model": …}``.

    Raises
    ------
    ArgumentError
        A plant built from CasADi functions: it has no expressions a plant file could hold.
    """
    ex = plant.expressions
    if not ex:
        raise ArgumentError(
            "this nonlinear plant was built from CasADi functions, which a plant file cannot hold; "
            "build it with NonlinearPlant.from_expressions to write it as TOML"
        )
    groups = {"states": plant.states, "inputs": plant.inputs, "outputs": plant.outputs, "parameters": plant.parameters}
    model: dict[str, Any] = {"time": "nonlinear"}
    if plant.Ts is not None:
        model["Ts"] = float(plant.Ts)
    model["f"] = dict(ex["f"])
    model["h"] = dict(ex["h"])
    model["nominal"] = {q: float(v) for q, v in zip(plant.parameters, np.asarray(plant.theta_nominal, dtype=float).tolist(), strict=True)}
    if ex.get("constants"):
        model["constants"] = {k: float(v) for k, v in ex["constants"].items()}
    model["Q_sample"] = np.asarray(plant.Q, dtype=float).tolist()
    model["R"] = np.asarray(plant.R, dtype=float).tolist()
    return {"signals": _signals(plant, groups), "model": model}


def plant_file_text(tables: Mapping[str, Any], name: str, *, title: str | None = None, design: Mapping[str, Any] | None = None,
                    designs: Mapping[str, Mapping[str, Any]] | None = None, simulation: Mapping[str, Any] | None = None,
                    scenarios: Sequence[Mapping[str, Any]] = ()) -> str:  # fmt: skip
    """A whole plant file: ``name``, ``title``, the plant's tables and the optional sections, as TOML.

    Parameters
    ----------
    tables : Mapping
        ``[signals]`` and ``[model]`` (:func:`linear_tables`, :func:`nonlinear_tables`).
    name : str
        The problem's name (it prefixes the C API).
    title : str, optional
        The report's title.
    design : Mapping, optional
        ``[design]``: ``method`` and its options.
    designs : Mapping of str to Mapping, optional
        ``[[designs]]``: several designs by name, each ``method`` and its options (not with ``design``).
    simulation : Mapping, optional
        ``[simulation]``.
    scenarios : sequence of Mapping
        ``[[scenarios]]``.

    Returns
    -------
    str
        The TOML text.

    Raises
    ------
    ArgumentError
        Both ``design`` and ``designs``, or a value a plant file cannot hold.
    """
    if design is not None and designs is not None:
        raise ArgumentError("give design (one design) or designs (several, by name), not both")
    for what, table in (("design", design), ("simulation", simulation)):
        if table is not None and not isinstance(table, Mapping):
            raise ArgumentError(f"{what} must be a mapping of its keys (as the plant file's [{what}] table); got {type(table).__name__}")
    if designs is not None and not (isinstance(designs, Mapping) and all(isinstance(v, Mapping) for v in designs.values())):
        raise ArgumentError("designs must map each design's name to a mapping of its method and options, "
                            "e.g. {'kalman': {'method': 'kalman_uio'}}")
    if isinstance(scenarios, (str, Mapping)) or not all(isinstance(x, Mapping) for x in scenarios):
        raise ArgumentError("scenarios must be a list of mappings, one per [[scenarios]] table, e.g. "
                            "[{'name': 'bias', 'duration': 10.0, 'fault': 'y1', 'onset': 5.0}]")
    doc: dict[str, Any] = {"name": name}
    if title is not None:
        doc["title"] = title
    doc.update(tables)
    if design is not None:
        doc["design"] = dict(design)
    if designs is not None:
        if not designs:
            raise ArgumentError("designs must map each design's name to its method and options, e.g. {'kalman': {'method': 'kalman_uio'}}")
        doc["designs"] = [{"name": k, **dict(v)} for k, v in designs.items()]
    if simulation is not None:
        doc["simulation"] = dict(simulation)
    if scenarios:
        doc["scenarios"] = [dict(s) for s in scenarios]
    return toml_text(doc)
