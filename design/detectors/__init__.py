"""Residual evaluation: each detector's statistic and its threshold from the statistic's law (χ², WSSR, CUSUM, GLR).

Importing the package imports each of its modules, so that every detector registers its entry in
:data:`fdisyn.detectors.table.DETECTORS` (kept in the order of :data:`fdisyn.runtime.schema.EVALUATOR_KINDS`):
a new detector is a new module here and its statistic in :mod:`fdisyn.runtime.statistics`.
"""

import importlib as _importlib
import pkgutil as _pkgutil

for _module in _pkgutil.iter_modules(__path__):
    _importlib.import_module(f"{__name__}.{_module.name}")
