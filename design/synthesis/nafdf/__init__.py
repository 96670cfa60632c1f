"""The nonlinear adaptive fault-detection filter, NAFDF (Zhou, Xi & Zhang, Shanghai Jiao Tong University, c. 1991).

``settings`` (options, validation, state layout), ``step`` (the CasADi step, fig. 1),
``design`` (design and certificate), ``payload`` (the gain file's ``nafdf`` payload),
``method`` (the design method ``nafdf`` of :mod:`fdisyn.synthesis.registry`), ``kind`` (the ``nafdf``
diagnoser kind of :mod:`fdisyn.synthesis.kinds`).
"""

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
    "nafdf",
    "nafdf_extra_metrics",
    "nafdf_from_gain_file",
    "nafdf_from_payload",
    "nafdf_gain_file",
    "nafdf_payload",
    "step_from_payload",
]
