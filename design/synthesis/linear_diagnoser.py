"""Assemble a linear diagnoser: generators + χ² evaluators + signature decision.

The result is a :class:`~fdisyn.runtime.gainfile.GainFile`, the unit that is
written to disk and to C. Signatures are derived, not typed in: a sensor fault
is expected to raise statistic ``j`` when its sensor is among the outputs of
``j``'s generator, and the certificate checks that the generator is in fact
sensitive to it (a nonzero steady-state gain from the sensor to the residual).
"""

from __future__ import annotations

import datetime as _dt
import platform
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from fdisyn.evaluators.chi2 import chi2_evaluator
from fdisyn.models.linear import LinearPlant
from fdisyn.numerics.linalg import transfer_size
from fdisyn.runtime.errors import ShapeError
from fdisyn.runtime.gainfile import (
    Decision,
    Evaluator,
    GainFile,
    Generator,
    StepSpec,
    linear_state_layout,
)
from fdisyn.synthesis.certificate import Certificate, Check
from fdisyn.synthesis.residual import dc_gain_y, internal_form

__all__ = ['FaultClass', 'default_fault_classes', 'linear_diagnoser', 'provenance']


@dataclass(frozen=True)
class FaultClass:
    """A fault class of the decision table: the sensors and component faults it corrupts.

    ``sensors`` name plant outputs (additive sensor faults); ``components``
    name plant component faults (the columns of ``Fx``).
    """

    name: str
    sensors: tuple[str, ...] = ()
    components: tuple[str, ...] = ()




def provenance(**extra: object) -> dict[str, object]:
    """Where a gain file came from: versions, machine, time, design options."""
    import casadi
    import scipy

    out: dict[str, object] = {
        "created_utc": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "python": sys.version.split()[0],
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "casadi": str(getattr(casadi, "__version__", "unknown")),
        "platform": platform.platform(),
    }
    try:
        from importlib.metadata import version

        out["fdisyn"] = version("fdisyn")
    except Exception:  # noqa: BLE001 - an uninstalled checkout has no metadata
        out["fdisyn"] = "unknown"
    out.update(extra)
    return out


def linear_diagnoser(
    *,
    name: str,
    problem: str,
    design: str,
    plant: LinearPlant,
    generators: Sequence[Generator],
    sigma_r: Sequence[np.ndarray],
    P_f: float,
    faults: Sequence[FaultClass],
    certificates: Sequence[Certificate],
    persistence: int = 1,
    options: Mapping[str, object] | None = None,
) -> GainFile:
    """Build and check the gain file of a bank of linear residual generators.

    ``sigma_r[i]`` is generator ``i``'s steady-state residual covariance (from
    its design); each gets one χ² evaluator. ``faults`` name the fault classes
    to isolate; their signatures must be nonzero and distinct.
    """
    if not plant.is_discrete:
        raise ShapeError("linear_diagnoser needs the discrete plant the generators were designed on")
    if len(sigma_r) != len(generators) or len(certificates) != len(generators):
        raise ShapeError(f"{len(generators)} generators need as many residual covariances and certificates")
    if int(persistence) < 1:
        raise ShapeError(f"persistence must be a positive number of samples; got {persistence!r}")
    gens = list(generators)
    evals = [chi2_evaluator(i, s, P_f) for i, s in enumerate(sigma_r)]
    sig = np.array([[_expected(fault, gens[ev.generator], plant) for ev in evals] for fault in faults], dtype=int)
    checks, sensitivity = _bank_checks(generators, evals, plant)
    bank_cert = Certificate.of(f"{problem}/{design} bank", checks, {"min_detectable_bias": sensitivity}).require()
    nr = sum(g.n_residual for g in gens)
    lay = linear_state_layout(gens, len(evals))
    step = StepSpec(
        nu=plant.m,
        ny=plant.p,
        nr=nr,
        nj=len(evals),
        nstate=lay.size,
        init_state=np.zeros(lay.size),
        residual_names=tuple(_residual_names(gens, plant)),
        statistic_names=tuple(f"J_{gens[e.generator].name}" for e in evals),
    )
    return GainFile(
        kind="linear",
        name=name,
        problem=problem,
        design=design,
        Ts=float(plant.Ts),  # type: ignore[arg-type]
        inputs=plant.inputs,
        outputs=plant.outputs,
        faults=tuple(f.name for f in faults),
        step=step,
        plant=plant.matrices(),
        generators=tuple(gens),
        evaluators=tuple(evals),
        decision=Decision(kind="signature_table", signatures=sig, persistence=int(persistence)),
        certificate={
            "passed": True,
            "generators": [c.to_dict() for c in certificates],
            "bank": bank_cert.to_dict(),
        },
        provenance=provenance(options=dict(options or {})),
    )


def default_fault_classes(plant: LinearPlant, generators: Sequence[Generator]) -> list[FaultClass]:
    """One class per sensor and per component fault that reaches the bank; classes the
    bank cannot tell apart (equal signatures) are merged and named ``"a|b"``."""
    singles = [FaultClass(o, sensors=(o,)) for o in plant.outputs] + [
        FaultClass(c, components=(c,)) for c in plant.component_faults
    ]
    merged: dict[tuple[int, ...], list[FaultClass]] = {}
    for fault in singles:
        sig = tuple(_expected(fault, g, plant) for g in generators)
        if any(sig):
            merged.setdefault(sig, []).append(fault)
    return [
        FaultClass(
            "|".join(f.name for f in group),
            sensors=tuple(s for f in group for s in f.sensors),
            components=tuple(c for f in group for c in f.components),
        )
        for group in merged.values()
    ]


def _residual_names(gens: Sequence[Generator], plant: LinearPlant) -> list[str]:
    """``generator.output`` when a residual has one component per sensor it reads, else ``generator.r<k>``."""
    out: list[str] = []
    for g in gens:
        if g.n_residual == len(g.outputs_used):
            out.extend(f"{g.name}.{plant.outputs[j]}" for j in g.outputs_used)
        else:
            out.extend(f"{g.name}.r{k}" for k in range(g.n_residual))
    return out


def _expected(fault: FaultClass, gen: Generator, plant: LinearPlant) -> int:
    """1 when ``fault`` reaches ``gen``'s residual: it corrupts a sensor the generator
    reads, or a component fault's transfer to the residual is not identically zero."""
    for s in fault.sensors:
        if s not in plant.outputs:
            raise ShapeError(f"fault {fault.name!r} names sensor {s!r}; sensors are {list(plant.outputs)}")
    for c in fault.components:
        if c not in plant.component_faults:
            raise ShapeError(f"fault {fault.name!r} names component fault {c!r}; the plant has {list(plant.component_faults)}")
    if {plant.outputs.index(s) for s in fault.sensors} & set(gen.outputs_used):
        return 1
    form = internal_form(gen, plant)
    for c in fault.components:
        j = plant.component_faults.index(c)
        # round-off of an exactly decoupled transfer is ~1e-16; 1e-8 separates "reaches" from "cancels"
        if transfer_size(form.A, form.Bf[:, [j]], form.C, np.zeros((form.C.shape[0], 1))) > 1e-8:
            return 1
    return 0


def _bank_checks(
    generators: Sequence[Generator], evals: Sequence[Evaluator], plant: LinearPlant
) -> tuple[list[Check], dict[str, dict[str, float | None]]]:
    """Every sensor of the signature table must reach the statistic; how well, at steady state.

    Check: the transfer from an additive fault on sensor ``s`` to the residual
    (``Ar, By[:, s], Cr, Dy[:, s]``) is not identically zero (normalised Markov
    parameters above round-off). Information: the smallest constant bias that
    crosses the threshold on its own at steady state, ``b_min = sqrt(J_th / gᵀ W g)``
    with ``g`` the DC gain column (∞ when a bias is invisible at steady state,
    e.g. on a sensor of an integrating state: only its onset transient shows;
    reported as ``None``).
    """
    checks: list[Check] = []
    table: dict[str, dict[str, float | None]] = {}
    for ev in evals:
        gen = generators[ev.generator]
        dc = dc_gain_y(gen)
        row: dict[str, float | None] = {}
        for j in gen.outputs_used:
            g = dc[:, j]
            energy = float(g @ ev.W @ g)
            scale = float(np.linalg.norm(gen.Dy[:, j]) + np.linalg.norm(gen.Cr) * np.linalg.norm(gen.By[:, j]))
            visible = energy > 1e-20 * scale**2 * np.linalg.norm(ev.W, 2)  # a DC gain cancelled to round-off
            row[plant.outputs[j]] = float(np.sqrt(ev.threshold / energy)) if visible else None
            checks.append(
                Check(
                    f"{gen.name}: sensor {plant.outputs[j]} reaches the residual",
                    transfer_size(gen.Ar, gen.By[:, [j]], gen.Cr, gen.Dy[:, [j]]),
                    1e-8,
                    ">=",
                    "a sensor in the signature table must move the residual; a transfer cancelled to round-off "
                    "(~1e-16) would make its faults invisible",
                )
            )
        table[gen.name] = row
    return checks, table
