"""The step function of a diagnoser as one CasADi ``Function``, built by its kind's step builder
(:mod:`fdisyn.synthesis.kinds` holds the contract it is checked against)."""

from __future__ import annotations

import casadi as ca
from fdisyn.runtime.errors import GainFileError
from fdisyn.runtime.gainfile import GainFile
from fdisyn.synthesis.kinds import STEP_INPUTS, STEP_OUTPUTS

__all__ = ["step_function"]


def step_function(gf: GainFile) -> ca.Function:
    """The CasADi step of any diagnoser kind, built from its gain file alone.

    Parameters
    ----------
    gf : GainFile
        A gain file of a registered diagnoser kind.

    Returns
    -------
    casadi.Function
        The step, with the contract of :mod:`fdisyn.synthesis.kinds`.

    Raises
    ------
    GainFileError
        Its kind is registered by no module, or the kind's step builder broke the step contract.
    """
    from fdisyn.synthesis.kinds import get_kind

    fn = get_kind(gf.kind).step_builder(gf)
    if tuple(fn.name_in()) != STEP_INPUTS or tuple(fn.name_out()) != STEP_OUTPUTS:
        raise GainFileError(f"the {gf.kind!r} step builder broke the step contract: {fn}")
    return fn
