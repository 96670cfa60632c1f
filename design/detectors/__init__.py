"""Residual evaluation: each detector's statistic and its threshold from the statistic's law (χ², WSSR, CUSUM, GLR).

Importing the package registers every detector in :data:`fdisyn.detectors.table.DETECTORS`, in the order of
:data:`fdisyn.runtime.schema.EVALUATOR_KINDS`.
"""

from fdisyn.detectors import chi2 as _chi2  # noqa: F401  (registration, in this order)
from fdisyn.detectors import wssr as _wssr  # noqa: F401
from fdisyn.detectors import sequential as _sequential  # noqa: F401
