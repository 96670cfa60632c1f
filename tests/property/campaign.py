"""The cases of the linear property campaign: seeded random plants per method, and two named plants.

Each case is a :class:`~tests.property.plants.Case`: the badly scaled plant fdisyn gets, its well-conditioned model,
the design options (fdisyn's defaults, plus what a method requires: ``Ts`` for a continuous plant, the poles of
``uio_pole_placement``, the decay rate of ``beard_fdf``), and the independent test's verdict.
"""

from __future__ import annotations

import math
import zlib

import numpy as np

from tests.property.plants import (
    Case,
    _spectrum,
    beard_certificate,
    beard_plant,
    log_uniform,
    sampled_data_conditions,
    state_scaling,
    uio_conditions,
    uio_plant,
    user_plant,
)

UIO_METHODS = ("kalman_uio", "kalman_uio_paper", "uio_pole_placement", "kalman_uio_gos")
SAMPLED_DATA_METHODS = ("lmi", "sampled_data_observer")
METHODS = (*UIO_METHODS, *SAMPLED_DATA_METHODS, "beard_fdf")
PLANTS = 6
"""Seeded plants per method."""
MAX_STATES = {"lmi": 8, "beard_fdf": 8}
"""Largest plant per method where 12 states would cost the campaign its time: the SDPs of ``lmi`` grow as n⁴ in the
solver, and an optimised Beard eigenstructure that fails runs its IPOPT starts for minutes on 10 states."""


def _rng(method: str, seed: int) -> np.random.Generator:
    return np.random.default_rng([zlib.crc32(method.encode()), seed])


def _uio_case(method: str, seed: int) -> Case:
    rng = _rng(method, seed)
    gos = method == "kalman_uio_gos"
    q = 2 if rng.random() < 0.35 else 1
    n_lo = q + 2 if gos else q + 1
    n = int(rng.integers(max(2, n_lo), 13))
    p_lo = q + 2 if gos else q + 1
    p = int(rng.integers(p_lo, min(n, q + 3) + 1))
    ts = log_uniform(rng, 1e-3, 1.0)
    omega = log_uniform(rng, 0.05, 1.0) / ts
    unstable = bool(rng.random() < 0.35)
    discrete = bool(rng.random() < 0.6)
    lam = _spectrum(rng, n, omega, unstable)
    zeros: list[float] = []
    zkind = "none"
    if discrete and n - q >= 1:
        u = rng.random()
        if u < 0.4:
            zkind = "stable-zero"
            zeros = [float(np.exp(-omega * ts * rng.uniform(0.2, 2.0)) * (1 if rng.random() < 0.7 else -1))]
        elif u < 0.55:
            zkind = "unstable-zero"
            zeros = [float(rng.uniform(1.1, 1.5))]
    if discrete:
        good = uio_plant(rng, n=n, q=q, p=p, spectrum=np.exp(lam * ts), zeros=zeros, scale=1.0)
    else:
        good = uio_plant(rng, n=n, q=q, p=p, spectrum=lam, scale=omega)
    decades = float(rng.choice([0.0, 2.0, 4.0, 6.0]))
    s = state_scaling(rng, n, decades)
    qn = 1e-4 * (1.0 if discrete else omega) * np.eye(n)
    plant = user_plant(good, s, Qc=qn, R=1e-4 * np.eye(p), Ts=ts if discrete else None)
    case = Case(
        id=f"{method}-seed{seed}-n{n}-q{q}-p{p}-{'disc' if discrete else 'cont'}-{'unst' if unstable else 'stab'}-{zkind}-Ts{ts:.0e}-spread1e{decades:.0f}",
        method=method, plant=plant, good={**good, "S": s}, Ts=ts, continuous=not discrete, options={}, exists=False, why="",
    )
    if not discrete:
        case.options["Ts"] = ts
    if method == "uio_pole_placement":
        case.options["poles"] = [float(v) for v in np.linspace(0.1, 0.6, n)]
    dg = case.discrete_good()
    if gos:
        conds = [uio_conditions(dg["A"], dg["E"], np.delete(dg["C"], j, axis=0)) for j in range(p)]
        bad = [(j, w) for j, (ok, w) in enumerate(conds) if not ok]
        case.exists = not bad and np.linalg.matrix_rank(dg["C"]) == p
        case.why = "; ".join(f"without y{j}: {w}" for j, w in bad) or "every sensor's UIO: " + conds[0][1]
    else:
        case.exists, case.why = uio_conditions(dg["A"], dg["E"], dg["C"], all_poles=method == "uio_pole_placement")
    case.extra["zeros_planted"] = zeros
    return case


def _sampled_data_case(method: str, seed: int) -> Case:
    rng = _rng(method, seed)
    q = 2 if rng.random() < 0.35 else 1
    n = int(rng.integers(max(2, q + 1), MAX_STATES.get(method, 12) + 1))
    p = int(rng.integers(q + 1, min(n, q + 2) + 1))
    ts = log_uniform(rng, 1e-3, 1.0)
    omega = log_uniform(rng, 0.05, 1.0) / ts
    unstable = bool(rng.random() < 0.35)
    lam = _spectrum(rng, n, omega, unstable)
    good = uio_plant(rng, n=n, q=q, p=p, spectrum=lam, scale=omega)
    decades = float(rng.choice([0.0, 2.0, 4.0, 6.0]))
    s = state_scaling(rng, n, decades)
    plant = user_plant(good, s, Qc=1e-4 * omega * np.eye(n), R=1e-4 * np.eye(p), Ts=None)
    exists, why = sampled_data_conditions(good["A"], good["E"], good["C"], ts)
    return Case(
        id=f"{method}-seed{seed}-n{n}-q{q}-p{p}-cont-{'unst' if unstable else 'stab'}-Ts{ts:.0e}-spread1e{decades:.0f}",
        method=method, plant=plant, good={**good, "S": s}, Ts=ts, continuous=True, options={"Ts": ts}, exists=exists, why=why,
    )


def _beard_case(seed: int) -> Case:
    rng = _rng("beard_fdf", seed)
    n = int(rng.integers(2, MAX_STATES["beard_fdf"] + 1))
    k = int(rng.integers(1, min(3, n) + 1))
    p = int(rng.integers(k, min(n, k + 2) + 1))
    planes = 1 if (n >= k + 1 and rng.random() < 0.35) else 0
    ts = log_uniform(rng, 1e-3, 1.0)
    a_ts = rng.uniform(0.05, 0.5)
    radius = math.exp(-a_ts)
    unstable = bool(rng.random() < 0.35)
    good = beard_plant(rng, n=n, k=k, p=p, radius=radius, planes=planes, unstable=unstable)
    decades = float(rng.choice([0.0, 2.0, 4.0, 6.0]))
    s = state_scaling(rng, n, decades)
    plant = user_plant(good, s, Qc=1e-4 * np.eye(n), R=1e-4 * np.eye(p), Ts=ts)
    exists, why = beard_certificate(good["A"], good["C"], good["spaces"], good["L"], radius)
    return Case(
        id=f"beard_fdf-seed{seed}-n{n}-k{k}-p{p}-planes{planes}-{'unst' if unstable else 'stab'}-Ts{ts:.0e}-spread1e{decades:.0f}",
        method="beard_fdf", plant=plant, good={**good, "S": s}, Ts=ts, continuous=False,
        options={"decay_rate": a_ts / ts}, exists=exists, why=why, extra={"radius": radius},
    )


def seeded_case(method: str, seed: int) -> Case:
    if method in UIO_METHODS:
        return _uio_case(method, seed)
    if method in SAMPLED_DATA_METHODS:
        return _sampled_data_case(method, seed)
    return _beard_case(seed)


# --------------------------------------------------------------------------- named plants


def mass_spring(*, beard: bool = False) -> dict[str, np.ndarray]:
    """Two masses in SI units: ground –k1,c1– m1 –k2,c2– m2; the input pushes m1, an unknown force pushes m2.

    States ``x1, v1, x2, v2`` (m, m/s); sensors ``x1, x2, v2`` (two positions, one velocity: the unknown force
    reaches ``v2`` within a sample). Beard variant: the two forces are the component faults (no unknown input).
    """
    m1, m2, k1, k2, c1, c2 = 2.0, 5.0, 2.0e4, 1.0e4, 20.0, 10.0
    a = np.array([
        [0.0, 1.0, 0.0, 0.0],
        [-(k1 + k2) / m1, -(c1 + c2) / m1, k2 / m1, c2 / m1],
        [0.0, 0.0, 0.0, 1.0],
        [k2 / m2, c2 / m2, -k2 / m2, -c2 / m2],
    ])
    b = np.array([[0.0], [1.0 / m1], [0.0], [0.0]])
    e = np.array([[0.0], [0.0], [0.0], [1.0 / m2]])
    c = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]])
    if beard:
        return {"A": a, "B": b, "C": c, "E": np.zeros((4, 0)), "Fx": np.hstack([b, e])}
    return {"A": a, "B": b, "C": c, "E": e, "Fx": b}


MASS_SPRING_TS = 0.01


def mass_spring_case(method: str) -> Case:
    from fdisyn.models.linear import LinearPlant

    g = mass_spring(beard=method == "beard_fdf")
    names = {"states": ["x1", "v1", "x2", "v2"], "inputs": ["u"], "outputs": ["y_x1", "y_x2", "y_v2"]}
    qc = np.diag([0.0, 1.0 / 2.0**2, 0.0, 1.0 / 5.0**2])  # 1 N²·s of force noise on each mass
    r = np.diag([1e-8, 1e-8, 1e-6])  # 0.1 mm, 1 mm/s
    if method == "beard_fdf":
        plant = LinearPlant.create(A=g["A"], B=g["B"], C=g["C"], Fx=g["Fx"], Q=qc, R=r, component_faults=["f_m1", "f_m2"], **names)
    else:
        plant = LinearPlant.create(A=g["A"], B=g["B"], C=g["C"], E=g["E"], Fx=g["Fx"], Q=qc, R=r, unknown_inputs=["d_m2"],
                                   component_faults=["f_m1"], **names)
    case = Case(id=f"{method}-mass_spring_SI-Ts10ms", method=method, plant=plant, good={**g, "S": np.ones(4)}, Ts=MASS_SPRING_TS,
                continuous=True, options={"Ts": MASS_SPRING_TS}, exists=False, why="")
    dg = case.discrete_good()
    if method == "kalman_uio":
        case.options["bank"] = [["y_x1", "y_v2"], ["y_x2", "y_v2"]]
        conds = [uio_conditions(dg["A"], dg["E"], dg["C"][idx]) for idx in ([0, 2], [1, 2])]
        case.exists = all(ok for ok, _ in conds)
        case.why = "; ".join(w for _, w in conds)
    elif method == "kalman_uio_gos":
        case.options["sensors"] = ["y_x1", "y_x2"]  # without y_v2 the unknown force reaches no sensor within a sample
        conds = [uio_conditions(dg["A"], dg["E"], dg["C"][idx]) for idx in ([1, 2], [0, 2])]
        case.exists = all(ok for ok, _ in conds)
        case.why = "; ".join(w for _, w in conds)
    else:
        case.options["decay_rate"] = 1.0
        radius = math.exp(-1.0 * MASS_SPRING_TS)
        case.extra["radius"] = radius
        spaces, gain = beard_witness(dg["A"], dg["C"], dg["Fx"], radius)
        case.good["spaces"] = spaces
        case.exists, case.why = (False, "no witness gain") if gain is None else beard_certificate(dg["A"], dg["C"], spaces, gain, radius)
    return case


BEARD_TEXTBOOK_DECAY = 2.0


def beard_textbook_case() -> Case:
    """The three-state textbook plant of ``design/examples/beard_textbook.toml`` (unstable open loop, two isolable
    faults) at its Ts = 0.1 s, with the default (optimised) eigenstructure and its decay rate."""
    from fdisyn.models.linear import LinearPlant

    a = np.array([[0.0, 1.0, 0.0], [0.01, 0.0, 1.0], [0.0, 0.0, -1.0]])
    b = np.array([[0.0], [0.0], [1.0]])
    c = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    fx = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    plant = LinearPlant.create(A=a, B=b, C=c, Fx=fx, Q=np.diag([0.0, 1e-4, 1e-4]), R=1e-4 * np.eye(2),
                               states=["x_pos", "x_vel", "x_act"], inputs=["u"], outputs=["y_pos", "y_act"],
                               component_faults=["f_push", "f_act"])
    ts = 0.1
    case = Case(id="beard_fdf-textbook-optimised", method="beard_fdf", plant=plant, good={"A": a, "B": b, "C": c, "E": np.zeros((3, 0)),
                "Fx": fx, "S": np.ones(3)}, Ts=ts, continuous=True, options={"Ts": ts, "decay_rate": BEARD_TEXTBOOK_DECAY},
                exists=False, why="")
    radius = math.exp(-BEARD_TEXTBOOK_DECAY * ts)
    case.extra["radius"] = radius
    dg = case.discrete_good()
    # f_push's sampled detection space is the A-invariant plane span{e_pos, e_vel} (the example file's derivation)
    plane = np.eye(3)[:, :2]
    spaces, gain = beard_witness(dg["A"], dg["C"], dg["Fx"], radius, [plane, detection_space(dg["A"], dg["C"], dg["Fx"][:, 1])])
    case.good["spaces"] = spaces
    case.exists, case.why = (False, "no witness gain") if gain is None else beard_certificate(dg["A"], dg["C"], spaces, gain, radius)
    return case


def detection_space(a: np.ndarray, c: np.ndarray, f: np.ndarray) -> np.ndarray:
    """``span{f, A f, …, A^{ν−1} f}`` with ``ν`` the first power where ``C A^{ν−1} f ≠ 0`` (the detection space of a
    fault without invariant zeros, Massoumnia, IEEE TAC 31(9), 1986)."""
    cols = [f / np.linalg.norm(f)]
    while np.linalg.norm(c @ cols[-1]) <= 1e-9 * np.linalg.norm(c, 2) and len(cols) < a.shape[0]:
        nxt = a @ cols[-1]
        cols.append(nxt / np.linalg.norm(nxt))
    return np.linalg.qr(np.column_stack(cols))[0]


def beard_witness(ad: np.ndarray, c: np.ndarray, fx: np.ndarray, radius: float, spaces: list[np.ndarray] | None = None) -> tuple[list[np.ndarray], np.ndarray | None]:
    """A Beard gain found from first principles: in a basis ``V = [T_1 … T_k, complement]`` the conditions "``T_i``
    invariant under ``A − L C``" are linear in ``L`` (the rows of ``V⁻¹ (A − L C) T_i`` outside block ``i``
    vanish); their least-squares solution plus a seeded search over their null space for a spectrum inside
    ``radius``. ``spaces`` default to :func:`detection_space` of each column of ``Fx``. ``None`` when no gain
    found keeps every space invariant with the spectrum inside ``radius``."""
    n = ad.shape[0]
    if spaces is None:
        spaces = [detection_space(ad, c, fx[:, i]) for i in range(fx.shape[1])]
    dims = [t.shape[1] for t in spaces]
    if sum(dims) > n:
        return spaces, None
    t_all = np.hstack(spaces)
    comp = np.linalg.svd(t_all.T)[2][t_all.shape[1] :].T if sum(dims) < n else np.zeros((n, 0))
    v = np.hstack([t_all, comp])
    vi = np.linalg.inv(v)
    p = c.shape[0]
    mask = np.zeros((n, n), dtype=bool)  # entries of V⁻¹ (A − L C) V that must vanish
    o = 0
    for d in dims:
        mask[:, o : o + d] = True
        mask[o : o + d, o : o + d] = False
        o += d
    base = (vi @ ad @ v)[mask]
    cols = []
    for j in range(n * p):
        e = np.zeros(n * p)
        e[j] = 1.0
        cols.append(-(vi @ e.reshape(n, p) @ c @ v)[mask])
    jac = np.column_stack(cols)
    l0, *_ = np.linalg.lstsq(jac, -base, rcond=None)
    null = np.linalg.svd(jac)[2][np.linalg.matrix_rank(jac) :].T
    rng = np.random.default_rng(0)
    for trial in range(3000):
        z = l0 + (null @ rng.standard_normal(null.shape[1]) * 10.0 ** rng.uniform(-2, 3) if null.size and trial else 0.0)
        if np.linalg.norm(jac @ z + base) > 1e-9 * max(1.0, float(np.linalg.norm(base))):
            return spaces, None  # the invariance conditions have no solution
        gain = z.reshape(n, p)
        if float(np.max(np.abs(np.linalg.eigvals(ad - gain @ c)))) < radius:
            return spaces, gain
    return spaces, None


NAMED = {
    "kalman_uio-mass_spring_SI-Ts10ms": lambda: mass_spring_case("kalman_uio"),
    "kalman_uio_gos-mass_spring_SI-Ts10ms": lambda: mass_spring_case("kalman_uio_gos"),
    "beard_fdf-mass_spring_SI-Ts10ms": lambda: mass_spring_case("beard_fdf"),
    "beard_fdf-textbook-optimised": beard_textbook_case,
}


def all_cases() -> dict[str, Case]:
    out = {}
    for method in METHODS:
        for seed in range(PLANTS):
            c = seeded_case(method, seed)
            out[c.id] = c
    for f in NAMED.values():
        c = f()
        out[c.id] = c
    return out
