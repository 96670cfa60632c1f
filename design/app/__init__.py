"""The application: command line, plant files, the reproduce pipeline, reports, benchmarks.
"""

from pathlib import Path

WORKDIR = Path(".fdisyn")
"""The default work folder of ``reproduce``, ``report``, ``evaluate`` and ``bench`` (``--workdir``): the
designs, generated C and compiled libraries, under ``<problem>/<design>``. A hidden folder of the current
directory, like ``.pytest_cache``: the builds stay with the reports they serve, two projects (or two
clones) never share one, and setuptools' own ``build/`` folder (``pip install .``) is left to it."""

DESIGN_EXTRA = "design"
"""The optional dependencies (``pip install 'fdisyn[design]'``) that designing, generating C, simulating,
evaluating and reporting need; the base installation is the runtime: NumPy and the compiled library."""

DESIGN_PACKAGES = ("casadi", "cvxpy", "clarabel", "scipy", "matplotlib", "control", "slycot")
"""The import names of the packages of :data:`DESIGN_EXTRA` (each is also its distribution's name)."""


def missing_design_package(exc: ImportError) -> str | None:
    """The design package whose absence ``exc`` reports (``casadi`` for ``No module named 'casadi.tools'``),
    or ``None`` when ``exc`` concerns anything else."""
    root = (exc.name or "").partition(".")[0] if isinstance(exc, ModuleNotFoundError) else ""
    return root if root in DESIGN_PACKAGES else None
