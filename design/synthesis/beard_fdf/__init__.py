"""Beard's fault detection filter with the robust decision cones (He, Zhang & Wu, Journal of Astronautics, c. 1999).

``payload`` (the filter and the gain file's ``beard_fdf`` payload), ``step`` (the CasADi step),
``reference`` (its NumPy twin), ``method`` (the design method ``beard_fdf`` of
:mod:`fdisyn.synthesis.registry`), ``kind`` (the ``beard_fdf`` diagnoser kind of :mod:`fdisyn.synthesis.kinds`:
its recovery window, budget and account view).
"""

from fdisyn.synthesis.beard_fdf.payload import BeardFilter, beard_from_gain_file, beard_gain_file, beard_names
from fdisyn.synthesis.beard_fdf.reference import beard_reference_run
from fdisyn.synthesis.beard_fdf.step import beard_step, beard_step_function

__all__ = [
    "BeardFilter",
    "beard_from_gain_file",
    "beard_gain_file",
    "beard_names",
    "beard_reference_run",
    "beard_step",
    "beard_step_function",
]
