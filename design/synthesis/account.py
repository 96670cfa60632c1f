"""The account of what a diagnoser can see, for any kind: its kind's view of it (:attr:`DiagnoserKind.account_view`)
computed by :func:`fdisyn.numerics.account.bank_account`, stored in the gain file's ``account`` block.

The registry wraps every method's design with :func:`with_account`, so every way of designing stores it.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from fdisyn.numerics.account import NUMERIC_FAILURES, bank_account, unaccounted
from fdisyn.runtime.errors import ArgumentError
from fdisyn.runtime.gainfile import GainFile
from fdisyn.synthesis.kinds import get_kind

__all__ = ["fault_account", "with_account"]


def fault_account(gf: GainFile, plant: Any = None) -> dict[str, Any] | None:
    """What a diagnoser can see, before any Monte Carlo: each fault's effect, its smallest detectable size, the classes.

    Parameters
    ----------
    gf : GainFile
        A diagnoser of a kind with an account (linear, ``beard_fdf``). Without ``plant``, a gain file that holds an
        account returns it.
    plant : LinearPlant, optional
        The plant the design was made for (discrete, or continuous: then ZOH-sampled at ``gf.Ts``): its ``Fx`` gives
        the component faults, its ``units`` the faults' units, its ``Q`` and ``R`` the Beard filter's noise. Without
        it, the account covers the sensor faults only (and, for a Beard filter, no sizes).

    Returns
    -------
    dict or None
        The ``account`` block of the gain file (:func:`fdisyn.numerics.account.bank_account`; see the gain-file
        section of ``runtime/REFERENCE.md``). ``None`` for a kind the account does not cover (its
        :attr:`~fdisyn.synthesis.kinds.DiagnoserKind.account_note` says why).

    Raises
    ------
    ArgumentError
        ``gf`` is not a :class:`GainFile`.
    GainFileError
        Its kind is registered by no module.
    """
    if not isinstance(gf, GainFile):
        raise ArgumentError(f"gf must be a GainFile (from fdisyn.design or read_gain_file); got {type(gf).__name__}")
    if plant is None and gf.account is not None:
        return dict(gf.account)
    view = get_kind(gf.kind).account_view
    return None if view is None else bank_account(gf, view(gf), plant)


def with_account(gf: GainFile, plant: Any = None) -> GainFile:
    """``gf`` with its ``account`` block (:func:`fault_account`); unchanged for a kind the account does not cover.

    Parameters
    ----------
    gf : GainFile
        The certified gain file a design returned.
    plant : LinearPlant, optional
        The plant it was designed for (see :func:`fault_account`).

    Returns
    -------
    GainFile
        The same diagnoser (same generators, thresholds and certificate) with ``account`` set.

    Raises
    ------
    GainFileError
        Its kind is registered by no module.
    """
    if get_kind(gf.kind).account_view is None:
        return gf
    base = replace(gf, account=None) if gf.account is not None else gf
    try:
        block = fault_account(base, plant)
    except NUMERIC_FAILURES as exc:  # informational: a design that passed its certificate is not refused for its account
        block = unaccounted(gf, exc)
    return replace(gf, account=block)
