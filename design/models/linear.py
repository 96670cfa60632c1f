"""The linear plant every linear design method starts from.

``LinearPlant`` holds

    x⁺ = A x + B u + E d + Fx f + w        (discrete, ``Ts`` given)
    ẋ  = A x + B u + E d + Fx f + w        (continuous, ``Ts is None``)
    y  = C x + D u + Dd d + Df f + f_s + v

with ``u`` known inputs, ``d`` unknown inputs (disturbances), ``f`` component
or actuator faults with known directions (on states, sensors or both), ``f_s``
one additive fault per sensor, ``w ~ N(0, Q)`` and ``v ~ N(0, R)``.
For a continuous plant ``Q`` is the intensity (power spectral density) of
continuous white process noise and ``R`` the covariance of the sampled sensor
noise; ``discretise`` turns ``Q`` into the exact sampled covariance.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np
from fdisyn.models.sampling import check_sample_time, van_loan, zoh
from fdisyn.numerics.linalg import as_matrix, as_square, as_symmetric, frozen_array, real_array
from fdisyn.runtime.errors import ArgumentError, ShapeError
from fdisyn.runtime.schema import MAX_MAGNITUDE, SIGNAL_LABEL_MAX, UNIT_MAX
from fdisyn.runtime.names import (
    RESERVED_SIGNAL_NAMES,
    SIGNAL_NAME_MAX,
    check_distinct,
    check_signal_name,
    check_signal_names,
    check_signal_texts,
    shown,
)
from fdisyn.runtime.values import real_number

__all__ = ["LinearPlant", "identifier_names"]

BALANCING_ROUNDS = 8
"""Rounds of :func:`~fdisyn.numerics.linalg.state_balancing` in :meth:`LinearPlant.balancing` (each on the plant
scaled by the rounds before, its parts normalised again). Measured on 200 random plants with states spread over
six decades: 196 reach the fixed point within five rounds; the others keep moving single states by a factor of
two (each move shrinks its norms by 5 %), and stop after these rounds, balanced to within that factor."""


def identifier_names(given: Sequence[str] | None, what: str, *, count: int | None = None, prefix: str = "") -> tuple[str, ...]:
    """Signal names (grammar of :mod:`fdisyn.runtime.names`), unique, ``count`` of them (``None`` given: ``prefix0…``)."""
    if given is None:
        return tuple(f"{prefix}{i}" for i in range(count or 0))
    return check_signal_names(given, f"{what} names", count=count)


def _validated(
    *,
    A: object,
    B: object | None,
    C: object | None,
    D: object | None,
    Ts: object | None,
    E: object | None,
    Fx: object | None,
    Q: object | None,
    R: object | None,
    Dd: object | None,
    Df: object | None,
    states: Sequence[str] | None,
    inputs: Sequence[str] | None,
    unknown_inputs: Sequence[str] | None,
    outputs: Sequence[str] | None,
    component_faults: Sequence[str] | None,
    units: Mapping[str, str] | None,
    labels: Mapping[str, str] | None,
    state_scale: object | None,
    symmetrise: bool,
) -> dict[str, Any]:
    """Every field of a :class:`LinearPlant` from what a caller gave, checked (the rules of :meth:`LinearPlant.create`).

    ``symmetrise``: ``Q`` and ``R`` become ``(Q + Qᵀ)/2`` (:meth:`LinearPlant.create`); otherwise they are kept as
    given once they are symmetric to round-off (the constructor, which ``dataclasses.replace`` calls).
    """
    if C is None:
        raise ArgumentError("C, the output matrix (p × n), is required; expected LinearPlant(A, B, C, D, Ts) or LinearPlant.create(A=…, C=…)")
    a = as_square(A, "A")
    n = a.shape[0]
    c = as_matrix(C, "C", cols=n)
    p = c.shape[0]
    b = np.zeros((n, 0)) if B is None else as_matrix(B, "B", rows=n, cols=None if np.ndim(np.asarray(B)) == 2 else 1)
    m = b.shape[1]
    if D is not None and not isinstance(D, bool) and real_number(D) == 0.0:  # a scalar 0: control.ss's zero feed-through
        D = None
    d = np.zeros((p, m)) if D is None else as_matrix(D, "D", rows=p, cols=m)
    e = np.zeros((n, 0)) if E is None else as_matrix(E, "E", rows=n, cols=None if np.ndim(np.asarray(E)) == 2 else 1)
    fx = np.zeros((n, 0)) if Fx is None else as_matrix(Fx, "Fx", rows=n, cols=None if np.ndim(np.asarray(Fx)) == 2 else 1)
    dd = np.zeros((p, e.shape[1])) if Dd is None else as_matrix(Dd, "Dd", rows=p, cols=e.shape[1])
    df = np.zeros((p, fx.shape[1])) if Df is None else as_matrix(Df, "Df", rows=p, cols=fx.shape[1])
    q = np.zeros((n, n)) if Q is None else as_symmetric(Q, "Q", n, psd=True)
    r = np.zeros((p, p)) if R is None else as_symmetric(R, "R", p, psd=True)
    if not symmetrise:  # checked above; kept as given (a plant's own Q in other coordinates is symmetric to round-off only)
        q = q if Q is None else as_matrix(Q, "Q", rows=n, cols=n)
        r = r if R is None else as_matrix(R, "R", rows=p, cols=p)
    continuous = Ts is None or (not isinstance(Ts, bool) and real_number(Ts) == 0.0)  # dt = 0 in python-control
    ts = None if continuous else check_sample_time(Ts)
    for key, mat in (("A", a), ("B", b), ("C", c), ("D", d), ("E", e), ("Fx", fx), ("Dd", dd), ("Df", df), ("Q", q), ("R", r)):
        if mat.size and not np.max(np.abs(mat)) <= MAX_MAGNITUDE:  # its design's gain file could not hold it
            at = tuple(int(i) for i in np.unravel_index(int(np.argmax(np.abs(mat))), mat.shape))
            raise ArgumentError(
                f"{key}{list(at)} is {float(mat[at]):.3g}; a plant's entries must be at most {MAX_MAGNITUDE:g} in magnitude "
                "(a diagnoser's gain file holds no larger numbers): express the signals in larger units"
            )
    names = {
        "states": identifier_names(states, "state", count=n, prefix="x"),
        "inputs": identifier_names(inputs, "input", count=m, prefix="u"),
        "unknown inputs": identifier_names(unknown_inputs, "unknown input", count=e.shape[1], prefix="d"),
        "outputs": identifier_names(outputs, "output", count=p, prefix="y"),
        "component faults": identifier_names(component_faults, "component fault", count=fx.shape[1], prefix="f"),
    }
    check_distinct(names, why="they are columns of the trace CSV `fdisyn simulate` writes, and sensor and component faults name fault classes")
    signals = [nm for group in names.values() for nm in group]
    texts = {
        key: {} if given is None else check_signal_texts(given, key, signals, max_length=longest)
        for key, given, longest in (("units", units, UNIT_MAX), ("labels", labels, SIGNAL_LABEL_MAX))
    }
    scale = None
    if state_scale is not None:
        try:
            sc = real_array(state_scale, "state_scale").reshape(-1)
        except (ShapeError, ArgumentError):
            sc = np.array([np.nan])
        if sc.shape != (n,) or not np.all(np.isfinite(sc)) or np.any(sc <= 0):
            raise ArgumentError(f"state_scale must be None or {n} positive finite numbers; got {shown(state_scale)}")
        scale = tuple(float(v) for v in sc)
    return {
        "A": frozen_array(a),
        "B": frozen_array(b),
        "C": frozen_array(c),
        "D": frozen_array(d),
        "E": frozen_array(e),
        "Fx": frozen_array(fx),
        "Q": frozen_array(q),
        "R": frozen_array(r),
        "Ts": ts,
        "states": names["states"],
        "inputs": names["inputs"],
        "unknown_inputs": names["unknown inputs"],
        "outputs": names["outputs"],
        "component_faults": names["component faults"],
        "units": texts["units"],
        "labels": texts["labels"],
        "state_scale": scale,
        "Dd": frozen_array(dd),
        "Df": frozen_array(df),
    }


_CONTROL_DEFAULT = re.compile(r"[xuy]\[\d*\]\Z")
"""python-control's default signal labels (``x[0]``, ``u[1]``, ``y[2]``): no name the user chose."""


def _control_names(
    given: Sequence[str] | None, labels: Sequence[str] | None, prefix: str, attribute: str, keyword: str, *, offset: int = 0
) -> Sequence[str] | None:
    """The names :meth:`LinearPlant.from_control` uses for one group: ``given``, else ``sys``'s labels.

    A python-control default label becomes fdisyn's default name of its place in the group (``prefix`` and the
    index); ``None`` when every label is a default (the plant's own defaults then). A label that breaks the
    signal-name grammar is refused naming it, its place in ``sys`` and the keyword that names the group instead.
    """
    if given is not None or labels is None:
        return given
    labels = [str(lb) for lb in labels]
    if all(_CONTROL_DEFAULT.match(lb) for lb in labels):
        return None
    out = []
    for i, lb in enumerate(labels):
        if _CONTROL_DEFAULT.match(lb):
            out.append(f"{prefix}{i}")
            continue
        try:
            out.append(check_signal_name(lb, f"sys.{attribute}[{i + offset}]"))
        except ArgumentError:
            why = (
                f"it is reserved ({RESERVED_SIGNAL_NAMES[lb]})" if lb in RESERVED_SIGNAL_NAMES
                else f"expected a letter, then letters, digits or '_', at most {SIGNAL_NAME_MAX} characters"
            )
            raise ArgumentError(
                f"sys.{attribute}[{i + offset}] = {shown(lb)} cannot be an fdisyn signal name: {why}; "
                f"pass {keyword}=[…] to from_control to name them"
            ) from None
    return out


@dataclass(frozen=True, eq=False, init=False)
class LinearPlant:
    """A linear plant with unknown inputs, fault entries and Gaussian noise.

    Construct it as python-control's ``control.ss(A, B, C, D, dt)`` takes a system,
    ``LinearPlant(A, B, C, D, Ts, E=…, Q=…, R=…, outputs=[…], …)`` (``Ts`` ``None`` or 0: continuous), or with
    :meth:`create`'s keywords; both validate alike. Missing ``D``, ``E``, ``Fx``, ``Dd``, ``Df`` default to
    zero matrices of the right size, missing ``Q``/``R`` to zero. Every matrix
    is checked against the dimensions implied by ``A``, ``B`` and ``C``, every
    name against the signal-name grammar (:mod:`fdisyn.runtime.names`), and
    names are distinct across states, inputs, unknown inputs, outputs and
    component faults: they are all columns of the trace CSV ``fdisyn
    simulate`` writes, and sensor and component faults name fault classes.

    Attributes
    ----------
    A, B, C, D : numpy.ndarray
        The model ``ẋ = A x + B u + E d + Fx f`` (``x⁺`` when discrete), ``y = C x + D u + Dd d + Df f + f_s``
        (``f_s``: one sensor fault per output).
    E : numpy.ndarray
        The unknown inputs' entry (``n × q``): the disturbances the residuals are decoupled from.
    Fx : numpy.ndarray
        The component faults' entry (``n × len(component_faults)``); sensor faults need none.
    Dd, Df : numpy.ndarray
        The unknown inputs' and the component faults' direct reach into the outputs (``p × q``, ``p × f``; zero
        unless given): an unknown input or a component fault may act on states, on sensors or on both.
    Q, R : numpy.ndarray
        The process and measurement noise covariances (symmetric positive semidefinite).
    Ts : float or None
        The sample time in seconds; ``None`` for a continuous plant.
    states, inputs, unknown_inputs, outputs, component_faults : tuple of str
        The names of the states, known inputs, unknown inputs, outputs (the sensor faults' names too) and
        component faults.
    units : Mapping of str to str
        A unit per signal name (``"rad/s"``; informational: pages, messages and gain files show it).
    labels : Mapping of str to str
        A readable name per signal name, without its unit (``"rotor speed"``; informational, like ``units``).
    state_scale : tuple of float or None
        The typical state magnitudes the user chose (:meth:`scaled`; the plant file's ``[model].state_scale``):
        the linear methods design in these coordinates as given. ``None``: they balance the states themselves
        (:meth:`balancing`).

    Examples
    --------
    >>> plant = LinearPlant.create(A=[[0.9]], B=[[1.0]], C=[[1.0]], E=[[0.1]], R=[[0.01]], Ts=0.1)
    >>> plant.n, plant.m, plant.p, plant.q
    (1, 1, 1, 1)
    >>> LinearPlant([[0.9]], [[1.0]], [[1.0]], 0, 0.1, E=[[0.1]], R=[[0.01]]).q
    1
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    E: np.ndarray
    Fx: np.ndarray
    Q: np.ndarray
    R: np.ndarray
    Ts: float | None
    states: tuple[str, ...]
    inputs: tuple[str, ...]
    unknown_inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    component_faults: tuple[str, ...]
    units: Mapping[str, str] = field(default_factory=dict)
    state_scale: tuple[float, ...] | None = None
    Dd: np.ndarray = None  # type: ignore[assignment]  # zeros (p × q) when not given
    Df: np.ndarray = None  # type: ignore[assignment]  # zeros (p × f) when not given
    labels: Mapping[str, str] = field(default_factory=dict)

    def __init__(
        self,
        A: object,
        B: object | None = None,
        C: object | None = None,
        D: object | None = None,
        Ts: float | None = None,
        *,
        E: object | None = None,
        Fx: object | None = None,
        Q: object | None = None,
        R: object | None = None,
        Dd: object | None = None,
        Df: object | None = None,
        states: Sequence[str] | None = None,
        inputs: Sequence[str] | None = None,
        unknown_inputs: Sequence[str] | None = None,
        outputs: Sequence[str] | None = None,
        component_faults: Sequence[str] | None = None,
        units: Mapping[str, str] | None = None,
        labels: Mapping[str, str] | None = None,
        state_scale: Sequence[float] | None = None,
    ) -> None:
        """Validate and build a plant, positionally as ``control.ss(A, B, C, D, dt)``.

        Every argument is that of :meth:`create` and is checked by the same rules, with the same refusals:
        ``LinearPlant(A, B, C, D, Ts, **kw)`` and ``LinearPlant.create(A=A, B=B, C=C, D=D, Ts=Ts, **kw)`` give
        the same plant. One difference: :meth:`create` stores ``(Q + Qᵀ)/2`` and ``(R + Rᵀ)/2``, the constructor
        ``Q`` and ``R`` as given once they are symmetric to round-off (so ``dataclasses.replace``, which calls it
        with a plant's own fields, changes nothing it is not asked to).

        Parameters
        ----------
        A : array_like
            The state matrix (``n × n``).
        B : array_like, optional
            The known inputs' entry (``n × m``); default: no inputs.
        C : array_like
            The output matrix (``p × n``); required.
        D : array_like, optional
            The feed-through (``p × m``); default zero (a scalar 0, as python-control takes it, is zero too).
        Ts : float, optional
            The sample time in seconds; ``None`` or 0 (python-control's ``dt = 0``): a continuous plant.
        E, Fx, Q, R, Dd, Df : array_like, optional
            As in :meth:`create`.
        states, inputs, unknown_inputs, outputs, component_faults : sequence of str, optional
            As in :meth:`create`.
        units, labels : Mapping of str to str, optional
            As in :meth:`create`.
        state_scale : sequence of float, optional
            The typical state magnitudes the plant is designed in (:meth:`scaled` sets it); default ``None``.

        Raises
        ------
        ArgumentError
            As :meth:`create`; a ``state_scale`` that is not ``n`` positive finite numbers.
        ShapeError
            As :meth:`create`.
        """
        given = _validated(
            A=A, B=B, C=C, D=D, Ts=Ts, E=E, Fx=Fx, Q=Q, R=R, Dd=Dd, Df=Df, states=states, inputs=inputs,
            unknown_inputs=unknown_inputs, outputs=outputs, component_faults=component_faults, units=units, labels=labels,
            state_scale=state_scale, symmetrise=False,
        )
        for key, value in given.items():
            object.__setattr__(self, key, value)

    def _derived(self, **changes: Any) -> LinearPlant:
        """This plant with ``changes`` (fields computed from a valid plant by its own methods), not checked again."""
        out = object.__new__(type(self))
        for f in fields(self):
            object.__setattr__(out, f.name, changes[f.name] if f.name in changes else getattr(self, f.name))
        return out

    @classmethod
    def create(
        cls,
        *,
        A: object,
        B: object | None = None,
        C: object,
        D: object | None = None,
        E: object | None = None,
        Fx: object | None = None,
        Q: object | None = None,
        R: object | None = None,
        Ts: float | None = None,
        Dd: object | None = None,
        Df: object | None = None,
        states: Sequence[str] | None = None,
        inputs: Sequence[str] | None = None,
        unknown_inputs: Sequence[str] | None = None,
        outputs: Sequence[str] | None = None,
        component_faults: Sequence[str] | None = None,
        units: Mapping[str, str] | None = None,
        labels: Mapping[str, str] | None = None,
    ) -> LinearPlant:
        """Validate and build a plant from keywords (the constructor takes the same, ``A, B, C, D, Ts`` positionally).

        Parameters
        ----------
        A : array_like
            The state matrix (``n × n``).
        B : array_like, optional
            The known inputs' entry (``n × m``); default: no inputs.
        C : array_like
            The output matrix (``p × n``).
        D : array_like, optional
            The feed-through (``p × m``); default zero (a scalar 0 too, as python-control reads it).
        E : array_like, optional
            The unknown inputs' entry (``n × q``); default: none.
        Fx : array_like, optional
            The component faults' entry (``n × f``); default: none.
        Q, R : array_like, optional
            The process and measurement noise covariances; default zero.
        Ts : float, optional
            The sample time in seconds; default ``None``, a continuous plant (0 too: python-control's ``dt = 0``).
        Dd, Df : array_like, optional
            The unknown inputs' and the component faults' feed-through to the outputs (``p × q``, ``p × f``);
            default zero. A component fault given by ``Df`` alone acts on the sensors only.
        states, inputs, unknown_inputs, outputs, component_faults : sequence of str, optional
            The signal names (default ``x0 x1 …``, ``u0 …``, ``d0 …``, ``y0 …``, ``f0 …``): distinct across all
            of them, each following :mod:`fdisyn.runtime.names`.
        units : Mapping of str to str, optional
            A unit per signal name (``{"omega_r": "rad/s"}``): keys among the plant's signal names, each unit one
            line of at most :data:`~fdisyn.runtime.schema.UNIT_MAX` printable characters.
        labels : Mapping of str to str, optional
            A readable name per signal name, without its unit (``{"omega_r": "rotor speed"}``): keys among the
            plant's signal names, each at most :data:`~fdisyn.runtime.schema.SIGNAL_LABEL_MAX` printable characters.

        Returns
        -------
        LinearPlant
            The validated plant (its matrices read-only).

        Raises
        ------
        ArgumentError
            A matrix that is not real numbers, entries beyond 1e150, a covariance that is not symmetric
            positive semidefinite, a sample time that is not a positive number (or 0), a name that breaks the
            grammar or repeats another, or a unit or label of no signal of the plant or that is not short text.
        ShapeError
            A matrix whose size does not fit ``A``, ``B`` and ``C``.
        """
        plant = object.__new__(cls)
        given = _validated(
            A=A, B=B, C=C, D=D, Ts=Ts, E=E, Fx=Fx, Q=Q, R=R, Dd=Dd, Df=Df, states=states, inputs=inputs,
            unknown_inputs=unknown_inputs, outputs=outputs, component_faults=component_faults, units=units, labels=labels,
            state_scale=None, symmetrise=True,
        )
        for key, value in given.items():
            object.__setattr__(plant, key, value)
        return plant

    # dimensions -------------------------------------------------------------
    @property
    def n(self) -> int:
        """The number of states."""
        return self.A.shape[0]

    @property
    def m(self) -> int:
        """The number of known inputs."""
        return self.B.shape[1]

    @property
    def p(self) -> int:
        """The number of outputs."""
        return self.C.shape[0]

    @property
    def q(self) -> int:
        """The number of unknown inputs."""
        return self.E.shape[1]

    @property
    def is_discrete(self) -> bool:
        """The plant has a sample time."""
        return self.Ts is not None

    # transformations --------------------------------------------------------
    def discretise(self, Ts: float, *, name: str = "Ts") -> LinearPlant:
        """Exact ZOH sampling of a continuous plant.

        ``A_D = e^{A Ts}``; ``B``, ``E`` and ``Fx`` become step-invariant
        (inputs, disturbances and faults held over the sample); ``Q`` becomes
        the covariance of the sampled process noise (Van Loan); ``C``, ``D``,
        ``R`` are unchanged (sensors are sampled). A sample time so long that
        ``e^{±A Ts}`` overflows is refused naming ``name`` (the key the caller
        read it from) and the bound.

        Parameters
        ----------
        Ts : float
            The sample time in seconds.
        name : str
            What refusals call the sample time (the key the caller read it from).

        Returns
        -------
        LinearPlant
            The discrete plant.

        Raises
        ------
        ArgumentError
            The plant is discrete already, or ``Ts`` is not a positive number or so long that the
            exponential overflows.
        """
        if self.is_discrete:
            raise ArgumentError(f"the plant is already discrete (Ts = {self.Ts}); discretise a continuous plant")
        ts = check_sample_time(Ts, name)
        held = np.hstack([self.B, self.E, self.Fx])
        ad, bd_all = zoh(self.A, held, ts, name=name)
        m, q = self.m, self.q
        return self._derived(  # names, units, labels and state scaling kept
            A=frozen_array(ad),
            B=frozen_array(bd_all[:, :m]),
            E=frozen_array(bd_all[:, m : m + q]),
            Fx=frozen_array(bd_all[:, m + q :]),
            Q=frozen_array(van_loan(self.A, self.Q, ts, name=name)),
            Ts=ts,
        )

    def scaled(self, scale: Sequence[float] | np.ndarray) -> LinearPlant:
        """The plant in scaled states ``x̃ = S⁻¹ x`` with ``S = diag(scale)``.

        Input/output behaviour, and therefore every residual generator
        designed on it, is unchanged; only the conditioning of the state
        matrices improves when ``scale`` holds typical state magnitudes.
        The linear methods balance a plant's states themselves
        (:meth:`balancing`); a scaled plant overrides that: it is designed in
        the coordinates given (its :attr:`state_scale` records them).

        Parameters
        ----------
        scale : sequence of float
            ``n`` positive finite numbers: the typical magnitude of each state.

        Returns
        -------
        LinearPlant
            The plant in the scaled states.

        Raises
        ------
        ArgumentError
            ``scale`` is not ``n`` positive finite numbers.
        """
        try:
            s = real_array(scale, "state scaling").reshape(-1)  # numbers only: "10" or true are refused
        except (ShapeError, ArgumentError):
            raise ArgumentError(f"state scaling must be {self.n} positive finite numbers; got {scale!r}") from None
        if s.shape != (self.n,) or not np.all(np.isfinite(s)) or np.any(s <= 0):
            raise ArgumentError(f"state scaling must be {self.n} positive finite numbers; got {scale!r}")
        si = 1.0 / s
        return self._derived(  # names, units and labels kept
            A=frozen_array(si[:, None] * self.A * s[None, :]),
            B=frozen_array(si[:, None] * self.B),
            C=frozen_array(self.C * s[None, :]),
            E=frozen_array(si[:, None] * self.E),
            Fx=frozen_array(si[:, None] * self.Fx),
            Q=frozen_array(si[:, None] * self.Q * si[None, :]),
            state_scale=tuple(float(x) for x in (s if self.state_scale is None else s * np.asarray(self.state_scale))),
        )

    def balancing(self) -> np.ndarray:
        """The state scaling the linear methods design in when the user gave none: powers of two, from the plant
        and its noise.

        :func:`~fdisyn.numerics.linalg.state_balancing` of the system matrix
        ``[[A, E, Q^½], [C, 0, 0]]``, each of its parts in its own unit: every column of ``E`` (one unknown
        input) and the noise factor ``Q^½`` (as a whole: its directions keep their relative strengths) divided
        by its norm, every row of ``C`` (one sensor) by its norm. So the scaling depends on how the states are
        measured only, never on the units of the inputs or sensors, and it is exactly ``1`` for a plant whose
        states are balanced already (the parts' norms change with the states, so the balancing is repeated on the
        scaled plant until it is the identity, at most :data:`BALANCING_ROUNDS` times). The similarity
        ``x = diag(s) x̃`` (:meth:`scaled`) is exact in floating point: a generator designed on the scaled plant maps back to these states without round-off, and its
        residual is the same.

        Returns
        -------
        ndarray
            ``n`` positive powers of two (``1`` for every state of a balanced plant).
        """
        from fdisyn.numerics.linalg import state_balancing

        total = np.ones(self.n)
        for _ in range(BALANCING_ROUNDS):  # the parts' norms change with the states: balance until nothing moves
            s = state_balancing(*self._balancing_system(total))
            if np.all(s == s[0]):  # a common factor changes nothing: each part is normalised
                break
            total = total * s
        # centred (a common factor changes nothing, see above): a balanced plant gives exactly 1
        return total / np.exp2(np.round(np.median(np.log2(total)))) if self.n else total

    def _balancing_system(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(A, [E, Q^½], C)`` in the states ``x = diag(s) x̃``, each part in its own unit (:meth:`balancing`)."""
        si = 1.0 / s
        e = si[:, None] * np.asarray(self.E)
        norms = np.linalg.norm(e, axis=0)
        cols = [e[:, norms > 0] / norms[norms > 0]]
        lam, vec = np.linalg.eigh(si[:, None] * np.asarray(self.Q) * si[None, :])
        qh = vec * np.sqrt(np.clip(lam, 0.0, None))[None, :]
        if np.any(qh):
            cols.append(qh / np.linalg.norm(qh, 2))
        c = np.asarray(self.C) * s[None, :]
        rows = np.linalg.norm(c, axis=1)
        return si[:, None] * np.asarray(self.A) * s[None, :], np.hstack(cols), c[rows > 0] / rows[rows > 0, None]

    def with_noise(self, *, Q: object | None = None, R: object | None = None) -> LinearPlant:
        """The same plant with other noise covariances (validated like ``create``).

        Parameters
        ----------
        Q, R : array_like, optional
            The new process and measurement noise covariances; default: the plant's.

        Returns
        -------
        LinearPlant
            The plant with those covariances (its names, units, labels and state scaling kept).

        Raises
        ------
        ArgumentError
            A covariance that is not symmetric positive semidefinite.
        ShapeError
            A covariance of the wrong size.
        """
        plant = LinearPlant.create(
            A=self.A,
            B=self.B,
            C=self.C,
            D=self.D,
            E=self.E,
            Fx=self.Fx,
            Q=self.Q if Q is None else Q,
            R=self.R if R is None else R,
            Ts=self.Ts,
            Dd=self.Dd,
            Df=self.Df,
            states=self.states,
            inputs=self.inputs,
            unknown_inputs=self.unknown_inputs,
            outputs=self.outputs,
            component_faults=self.component_faults,
            units=self.units,
            labels=self.labels,
        )
        return plant._derived(state_scale=self.state_scale)

    def select_outputs(self, idx: Sequence[int]) -> LinearPlant:
        """The plant seen through a subset of its sensors (rows of ``C``, ``D``, ``R``).

        Parameters
        ----------
        idx : sequence of int
            The outputs to keep, in the order given.

        Returns
        -------
        LinearPlant
            The plant with those outputs; the units and labels of the outputs left out are dropped.

        Raises
        ------
        ArgumentError
            An index that is not a whole number or is out of range.
        """
        bad = [i for i in idx if isinstance(i, bool) or not isinstance(i, (int, np.integer))]
        if bad:  # int() would read the string "1" (and "１") and truncate 1.5
            raise ArgumentError(f"output indices must be whole numbers; got {shown(bad)}")
        ii = [int(i) for i in idx]
        for i in ii:
            if not 0 <= i < self.p:
                raise ArgumentError(f"output index {i} out of range 0..{self.p - 1}")
        dropped = set(self.outputs) - {self.outputs[i] for i in ii}
        return self._derived(
            C=frozen_array(self.C[ii, :]),
            D=frozen_array(self.D[ii, :]),
            Dd=frozen_array(self.Dd[ii, :]),
            Df=frozen_array(self.Df[ii, :]),
            R=frozen_array(self.R[np.ix_(ii, ii)]),
            outputs=tuple(self.outputs[i] for i in ii),
            units={k: v for k, v in self.units.items() if k not in dropped},
            labels={k: v for k, v in self.labels.items() if k not in dropped},
        )

    def matrices(self) -> dict[str, np.ndarray]:
        """The model matrices as a plain dict (for the gain file)."""
        return {k: np.asarray(getattr(self, k)) for k in ("A", "B", "C", "D", "E", "Q", "R")}

    def to_control(self) -> Any:
        """The plant as a python-control ``StateSpace`` with inputs ``[u; d]``: ``(A, [B E], C, [D Dd])``.

        ``dt`` is ``Ts`` (0 for a continuous plant); the signal names are kept
        (states, inputs then unknown inputs, outputs). The inverse of
        :meth:`from_control` with ``n_unknown = q``; ``Fx`` and the noise
        covariances have no place in a ``StateSpace`` and are left out.
        """
        import control

        return control.ss(
            self.A,
            np.hstack([self.B, self.E]),
            self.C,
            np.hstack([self.D, self.Dd]),
            dt=0 if self.Ts is None else self.Ts,
            states=list(self.states),
            inputs=[*self.inputs, *self.unknown_inputs],
            outputs=list(self.outputs),
        )

    @classmethod
    def from_control(
        cls,
        sys: Any,
        n_unknown: int = 0,
        Q: object | None = None,
        R: object | None = None,
        inputs: Sequence[str] | None = None,
        unknown_inputs: Sequence[str] | None = None,
        outputs: Sequence[str] | None = None,
        *,
        states: Sequence[str] | None = None,
        Fx: object | None = None,
        component_faults: Sequence[str] | None = None,
        units: Mapping[str, str] | None = None,
        labels: Mapping[str, str] | None = None,
    ) -> LinearPlant:
        """A plant from a python-control ``StateSpace`` whose last ``n_unknown`` inputs are unknown.

        ``sys = (A, [B E], C, [D Dd])``: the first ``m`` input columns are the
        known inputs ``u`` (``B``, ``D``), the last ``n_unknown`` the unknown
        inputs ``d`` (``E``, ``Dd``). A
        continuous ``sys`` (``dt = 0``) gives a continuous plant, a discrete
        one (``dt > 0``) a discrete plant with ``Ts = dt``. ``Q``, ``R``, the
        names and the rest are those of :meth:`create`. Names not given are
        ``sys``'s signal labels (``sys.state_labels``, ``sys.input_labels`` —
        the first ``m`` the inputs, the last ``n_unknown`` the unknown inputs —,
        ``sys.output_labels``), except python-control's own default labels
        (``x[0]``, ``u[0]``, ``y[0]``), which become fdisyn's (``x0``, ``u0``,
        ``d0``, ``y0``); a label outside fdisyn's name grammar
        (:mod:`fdisyn.runtime.names`) is refused, naming it::

            sys = control.c2d(control.ss(A, np.hstack([B, E]), C, 0), Ts)
            plant = LinearPlant.from_control(sys, n_unknown=1, Q=Q, R=R)

        Parameters
        ----------
        sys : control.StateSpace
            The plant, inputs ``[u; d]``; ``dt`` 0 (continuous) or the sample time.
        n_unknown : int
            How many of its last inputs are unknown inputs.
        Q, R : array_like, optional
            The process and measurement noise covariances; default zero.
        inputs, unknown_inputs, outputs, states, component_faults : sequence of str, optional
            The signal names, as in :meth:`create`; default: ``sys``'s labels (above).
        Fx : array_like, optional
            The component faults' entry, as in :meth:`create`.
        units, labels : Mapping of str to str, optional
            A unit and a readable name per signal name, as in :meth:`create`.

        Returns
        -------
        LinearPlant
            The validated plant.

        Raises
        ------
        ArgumentError
            ``sys`` is not a ``StateSpace``, ``n_unknown`` is out of range, ``sys.dt`` does not give the sample
            time, a label of ``sys`` used as a name is not a signal name, or :meth:`create` refuses the result.
        """
        import control

        if not isinstance(sys, control.StateSpace):
            raise ArgumentError(
                f"sys must be a control.StateSpace; got {type(sys).__name__} (convert a transfer function with control.ss(sys))"
            )
        a, b, c, d = (np.asarray(getattr(sys, k), dtype=float) for k in ("A", "B", "C", "D"))
        if isinstance(n_unknown, bool) or not isinstance(n_unknown, (int, np.integer)) or not 0 <= n_unknown <= b.shape[1]:
            raise ArgumentError(f"n_unknown must be a whole number in 0..{b.shape[1]} (sys has {b.shape[1]} inputs); got {n_unknown!r}")
        dt = sys.dt
        if dt is None or dt is True:
            raise ArgumentError(
                f"sys.dt = {dt!r} does not say the sample time; expected 0 (continuous) or the sample time in seconds"
            )
        m = b.shape[1] - int(n_unknown)
        in_labels = list(getattr(sys, "input_labels", None) or [])
        given = {
            "states": (states, getattr(sys, "state_labels", None), "x", "state_labels", "states"),
            "inputs": (inputs, in_labels[:m], "u", "input_labels", "inputs"),
            "unknown_inputs": (unknown_inputs, in_labels[m:], "d", "input_labels", "unknown_inputs"),
            "outputs": (outputs, getattr(sys, "output_labels", None), "y", "output_labels", "outputs"),
        }
        named = {key: _control_names(*spec, offset=m if key == "unknown_inputs" else 0) for key, spec in given.items()}
        return cls.create(
            A=a,
            B=b[:, :m],
            C=c,
            D=d[:, :m],
            E=b[:, m:],
            Dd=d[:, m:],
            Fx=Fx,
            Q=Q,
            R=R,
            Ts=None if dt == 0 else float(dt),
            states=named["states"],
            inputs=named["inputs"],
            unknown_inputs=named["unknown_inputs"],
            outputs=named["outputs"],
            component_faults=component_faults,
            units=units,
            labels=labels,
        )

    def to_toml(self, name: str = "plant", *, Ts: float | None = None, **sections: Any) -> str:
        """The plant as a TOML plant file that the plant-file reader reads back as this plant.

        The file holds ``[signals]`` (names, and ``units`` and ``labels`` when the plant has them) and ``[model]``;
        the process noise is written as ``Q_intensity`` (continuous) or ``Q_sample`` (discrete). Designing from
        the file gives the gain file :func:`fdisyn.design` gives for this plant with the same options.

        Parameters
        ----------
        name : str
            The problem's name (it prefixes the C API of its diagnosers).
        Ts : float, optional
            The diagnoser's sample time: required for a continuous plant, which the file samples at ``Ts``.
        **sections
            Optional sections of the file (:func:`fdisyn.models.plant_toml.plant_file_text`): ``title``,
            ``design`` (a mapping: ``method`` and its options), ``designs`` (several, by name), ``simulation``,
            ``scenarios``.

        Returns
        -------
        str
            The TOML text (write it to ``NAME.toml``; ``fdisyn design NAME.toml --out DIR`` designs from it).

        Raises
        ------
        ArgumentError
            A continuous plant without ``Ts``, or a section value a plant file cannot hold.

        Examples
        --------
        >>> plant = LinearPlant.create(A=[[0.9]], C=[[1.0]], R=[[0.01]], Ts=0.1)
        >>> print(plant.to_toml("tank").splitlines()[0])
        name = "tank"
        """
        from fdisyn.models.plant_toml import linear_tables, plant_file_text

        return plant_file_text(linear_tables(self, Ts=Ts), name, **sections)
