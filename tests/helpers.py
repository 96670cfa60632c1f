"""Helpers shared by the tests (seeded random systems)."""

from __future__ import annotations

import numpy as np
from fdisyn.models.linear import LinearPlant
from fdisyn.numerics.norms import DiscreteLTI


def random_plant(seed: int, *, n: int | None = None, p: int | None = None, q: int | None = None, radius: float | None = None) -> LinearPlant:
    """A random discrete plant with unknown inputs that meets the UIO conditions generically.

    ``A`` is scaled to spectral radius in [0.5, 1.3] (so unstable plants occur),
    ``Q``, ``R`` are random positive definite covariances.
    """
    rng = np.random.default_rng(seed)
    q = q if q is not None else int(rng.integers(1, 3))
    p = p if p is not None else int(rng.integers(q + 1, q + 3))
    n = n if n is not None else int(rng.integers(max(p, 2), 6))
    a = rng.standard_normal((n, n))
    rad = radius if radius is not None else float(rng.uniform(0.5, 1.3))
    a *= rad / max(abs(np.linalg.eigvals(a)))
    mq = rng.standard_normal((n, n))
    mr = rng.standard_normal((p, p))
    return LinearPlant.create(
        A=a,
        B=rng.standard_normal((n, 2)),
        C=rng.standard_normal((p, n)),
        E=rng.standard_normal((n, q)),
        Q=mq @ mq.T / n + 0.05 * np.eye(n),
        R=mr @ mr.T / p + 0.05 * np.eye(p),
        Ts=0.1,
    )


def random_stable(rng: np.random.Generator, n: int, m: int, p: int, *, radius: float = 0.9, d: bool = True) -> DiscreteLTI:
    """A random Schur-stable system with spectral radius ``radius``."""
    a = rng.standard_normal((n, n))
    a *= radius / max(np.abs(np.linalg.eigvals(a)))
    return DiscreteLTI.create(
        A=a,
        B=rng.standard_normal((n, m)),
        C=rng.standard_normal((p, n)),
        D=0.3 * rng.standard_normal((p, m)) if d else np.zeros((p, m)),
    )


def check_values(certificate: object) -> dict[str, list[float]]:
    """``name → values`` of every check in a :class:`Certificate` or a gain file's certificate
    document (its generators' and its bank's checks), for tests that judge the values
    themselves: a design whose certificate failed has raised, so ``passed`` is always true."""
    if hasattr(certificate, "checks"):
        rows = [(c.name, float(c.value)) for c in certificate.checks]  # type: ignore[attr-defined]
    else:
        doc = dict(certificate)  # type: ignore[call-overload]
        parts = [*doc.get("generators", []), *([doc["bank"]] if "bank" in doc else []), doc]
        rows = [(c["name"], float(c["value"])) for part in parts for c in part.get("checks", [])]
    out: dict[str, list[float]] = {}
    for name, value in rows:
        out.setdefault(name, []).append(value)
    return out


def coupling_markov(plant: dict, gen: object, count: int | None = None) -> tuple[float, float]:
    """How much ``u`` and ``d`` reach a generator's residual through the plant, computed here
    from the matrices alone: the largest Markov parameter of ``u → r`` and ``d → r`` of
    plant-in-series-with-generator, relative to the product of the norms that form it
    (0 for exact decoupling; round-off leaves ~1e-16)."""
    a, b, c, d, e = (np.asarray(plant[k], dtype=float) for k in ("A", "B", "C", "D", "E"))
    ar, bu, by, cr, du, dy = (np.asarray(getattr(gen, k), dtype=float) for k in ("Ar", "Bu", "By", "Cr", "Du", "Dy"))
    n, ns = a.shape[0], ar.shape[0]
    big_a = np.block([[a, np.zeros((n, ns))], [by @ c, ar]])
    big_c = np.hstack([dy @ c, cr])
    inputs = {"u": (np.vstack([b, by @ d + bu]), dy @ d + du), "d": (np.vstack([e, np.zeros((ns, e.shape[1]))]), np.zeros((cr.shape[0], e.shape[1])))}
    out = []
    for bb, dd in inputs.values():
        scale = max(np.linalg.norm(dy) * np.linalg.norm(d) + np.linalg.norm(du), np.finfo(float).tiny)
        worst = float(np.linalg.norm(dd)) / scale
        power = np.eye(n + ns)
        for _ in range(count or 2 * (n + ns)):
            term = big_c @ power @ bb
            worst = max(worst, float(np.linalg.norm(term)) / max(np.linalg.norm(big_c) * np.linalg.norm(power) * np.linalg.norm(bb), np.finfo(float).tiny))
            power = power @ big_a
        out.append(worst)
    return out[0], out[1]




def scenario_metrics(scenario: str, fault: str | None = None, *, Ts: float = 1.0, **figures: object) -> object:
    """A :class:`~fdisyn.evaluation.metrics.ScenarioMetrics` with the given ``figures`` and neutral others: what a
    problem's claims read, without a Monte Carlo."""
    from fdisyn.evaluation.metrics import ScenarioMetrics

    base: dict[str, object] = dict(
        scenario=scenario, fault=fault, runs=100, samples_per_run=1000, Ts=Ts, false_alarm_rate=0.0, false_alarm_runs=0.0,
        missed_detection_rate=None if fault is None else 0.0, missed_alarm_fraction=None, detection_delay_mean_s=None,
        detection_delay_median_s=None, detection_delay_max_s=None, detection_delay_mean_samples=None,
        detection_delay_max_samples=None, isolation_accuracy=None, first_isolation_accuracy=None,
        sample_isolation_accuracy=None, statistic_exceedance=[], statistic_exceedance_interval=[], fault_free_samples=100_000,
        nonfinite_samples=0,
    )
    return ScenarioMetrics(**{**base, **figures})  # type: ignore[arg-type]


def claims_context(problem: object, variants: list[dict]) -> object:
    """A report context whose variants hold only ``label``, ``options``, ``built`` (design → object with a
    ``gain_file``) and ``metrics`` (design → scenario → metrics): what :attr:`Problem.claims` reads."""
    from types import SimpleNamespace

    return SimpleNamespace(
        problem=problem,
        variants=[
            SimpleNamespace(
                label=v["label"], options=v.get("options", {}),
                built={d: SimpleNamespace(gain_file=gf) for d, gf in v.get("built", {}).items()},
                evaluation=SimpleNamespace(metrics=v["metrics"], examples={}, batches={}, runs=100),
            )
            for v in variants
        ],
    )


def check_claims(claims: list) -> None:
    """Every claim has a known verdict, and one that differs says why."""
    from fdisyn.reporting.kit import VERDICTS

    assert claims
    for c in claims:
        assert c.verdict in VERDICTS
        assert c.claim and c.paper and c.ours
        if c.verdict == "differs":
            assert len(c.why) > 20, c.claim
