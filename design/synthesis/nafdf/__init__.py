"""The nonlinear adaptive fault-detection filter, NAFDF (Zhou, Xi & Zhang, Shanghai Jiao Tong University, c. 1991).

``settings`` (options, validation, the state's blocks), ``step`` (the CasADi step, fig. 1),
``design`` (design and certificate), ``payload`` (the gain file's ``nafdf`` payload).
"""

from fdisyn.codegen.step import register_step_builder
from fdisyn.runtime.layout import StateLayout
from fdisyn.synthesis.nafdf.design import NafdfDesign, nafdf, nafdf_extra_metrics
from fdisyn.synthesis.nafdf.payload import (
    nafdf_from_gain_file,
    nafdf_from_payload,
    nafdf_gain_file,
    nafdf_payload,
    step_from_payload,
)
from fdisyn.synthesis.nafdf.settings import NafdfSettings

__all__ = [
    "NafdfDesign",
    "NafdfSettings",
    "StateLayout",
    "nafdf",
    "nafdf_extra_metrics",
    "nafdf_from_gain_file",
    "nafdf_from_payload",
    "nafdf_gain_file",
    "nafdf_payload",
    "step_from_payload",
]

register_step_builder("nafdf", lambda gf: nafdf_from_gain_file(gf).step)
