"""fdisyn — fault detection and isolation diagnosers designed as optimisation problems,
verified against independent truths and deployed as generated C.

The public Python API (see the README's "Python" section)::

    plant = fdisyn.LinearPlant.from_control(sys, n_unknown=1, Q=Q, R=R)
    gf = fdisyn.design(plant, method="kalman_uio", P_f=1e-4)   # a certified GainFile
    fdisyn.export(gf, "motor")                                  # gains.json, C sources, library, replay
    mon = fdisyn.load("motor")                                  # a Monitor
    fdisyn.methods()                                            # the registered method names
    fdisyn.fault_account(gf)                                    # what it can see (also gf.account)

The package root is light: the names above are imported on first use, so
``fdisyn.runtime`` (which never imports the design side) loads without CasADi
or cvxpy.
"""

from __future__ import annotations

from importlib import metadata as _metadata
from typing import TYPE_CHECKING, Any

try:
    __version__ = _metadata.version("fdisyn")
except _metadata.PackageNotFoundError:  # pragma: no cover - running from a source tree without an install
    __version__ = "0+unknown"

_PUBLIC = {
    "design": "fdisyn.app.api",
    "export": "fdisyn.app.api",
    "load": "fdisyn.app.api",
    "methods": "fdisyn.app.api",
    "problem": "fdisyn.app.api",
    "simulate": "fdisyn.app.api",
    "evaluate": "fdisyn.app.api",
    "fault_size_sweep": "fdisyn.app.api",
    "report": "fdisyn.app.api",
    "fault_account": "fdisyn.synthesis.account",
    "plot_trace": "fdisyn.reporting.plots",
    "plot_laws": "fdisyn.reporting.plots",
    "plot_detection": "fdisyn.reporting.plots",
    "structure_matrices": "fdisyn.synthesis.structure",
    "analyse_structure": "fdisyn.synthesis.structure",
    "check_structure": "fdisyn.synthesis.structure",
    "analyse_gaps": "fdisyn.synthesis.nullspace",
    "bank_performance": "fdisyn.synthesis.gap",
    "LinearPlant": "fdisyn.models.linear",
    "NonlinearPlant": "fdisyn.models.nonlinear",
    "SampledDataPlant": "fdisyn.models.sampled_data",
    "GainFile": "fdisyn.runtime.gainfile",
    "Monitor": "fdisyn.runtime.monitor",
}

__all__ = ["__version__", *_PUBLIC]

if TYPE_CHECKING:
    from fdisyn.app.api import design, evaluate, export, fault_size_sweep, load, methods, problem, report, simulate  # noqa: F401
    from fdisyn.synthesis.account import fault_account  # noqa: F401
    from fdisyn.reporting.plots import plot_detection, plot_laws, plot_trace  # noqa: F401
    from fdisyn.synthesis.structure import analyse_structure, check_structure, structure_matrices  # noqa: F401
    from fdisyn.synthesis.nullspace import analyse_gaps  # noqa: F401
    from fdisyn.synthesis.gap import bank_performance  # noqa: F401
    from fdisyn.models.linear import LinearPlant  # noqa: F401
    from fdisyn.models.nonlinear import NonlinearPlant  # noqa: F401
    from fdisyn.models.sampled_data import SampledDataPlant  # noqa: F401
    from fdisyn.runtime.gainfile import GainFile  # noqa: F401
    from fdisyn.runtime.monitor import Monitor  # noqa: F401


def __getattr__(name: str) -> Any:
    if name in _PUBLIC:
        import importlib

        value = getattr(importlib.import_module(_PUBLIC[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'fdisyn' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_PUBLIC))
