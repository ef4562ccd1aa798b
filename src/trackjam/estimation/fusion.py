"""Fusion of the agents' estimates (end of Section V-A).

The fused existence is the mean of the agents' existence probabilities,
``e_hat = mean{e^j}``. The agents that sense the target, ``N~ = {j | e^j > 0.5}``, combine
their means and covariances by covariance intersection (Julier & Uhlmann):

    C^{-1} = sum_j omega_j (C^j)^{-1},   x_hat = C sum_j omega_j (C^j)^{-1} x^j,

with the weights ``omega`` on the simplex that minimise ``trace(C)``.
"""

from __future__ import annotations

import math
import threading
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize, minimize_scalar

from trackjam.arguments import covariance, numeric, real, vector
from trackjam.estimation.bernoulli import Estimate, mix_visibility, posterior_visibility

CONFIRM = 0.5  # an agent senses the target when e^j > 0.5 (Section V-A)


@dataclass(frozen=True)
class FusedEstimate:
    existence: float  # e_hat, mean of the agents' e^j
    mean: np.ndarray | None  # (6,) fused state, None when no agent has e^j > 0.5
    cov: np.ndarray | None  # (6, 6)
    weights: np.ndarray  # omega_j per input estimate (0 for agents not in N~)
    visible: float | None = None  # P(visible | exists) with a hidden-target mode (ours), else None


COND_MAX = 1e10  # an estimate's covariance more ill-conditioned than this is floored before inversion

# SLSQP's weights depend on whether OpenBLAS runs threaded: single-threaded (OMP_NUM_THREADS=1,
# which Dask's workers set, or a one-core machine) they differed in the 8th digit from any
# threaded count (2, 3, 4 and 8 agree to the bit), and a sweep on Dask differed from the same
# sweep on the local pool. The search always runs with BLAS_THREADS threads, the count every
# committed result was computed with; the lock keeps two threads of one process from undoing
# each other's setting.
BLAS_THREADS = 2
_blas_lock = threading.Lock()
_blas = None


@contextmanager
def threaded_blas():
    """OpenBLAS at ``BLAS_THREADS`` threads while the block runs (about 11 us), then as it was."""
    global _blas
    with _blas_lock:
        if _blas is None:
            from threadpoolctl import ThreadpoolController

            _blas = ThreadpoolController().select(internal_api="openblas")
        with _blas.limit(limits=BLAS_THREADS):
            yield


def _conditioned(C: np.ndarray) -> np.ndarray:
    """``C``, or when it is (numerically) singular ``C`` loaded on its diagonal (every eigenvalue
    raised by the same amount) until its smallest is ``1 / COND_MAX`` of its largest: a
    ``filter.mode`` cluster of copies of one particle has no spread in position, and inverting
    that gave fused variances of -1e68. The covariances of an ordinary run (condition numbers of
    10 to 1000) are returned as they are."""
    C = np.asarray(C, dtype=float)
    eig = np.linalg.eigvalsh(0.5 * (C + C.T))
    floor = max(eig[-1], 1e-12) / COND_MAX
    if eig[0] >= floor:
        return C
    return 0.5 * (C + C.T) + (floor - eig[0]) * np.eye(len(C))


def _inverse(C: np.ndarray) -> np.ndarray:
    C = 0.5 * (C + C.T)
    try:
        return np.linalg.inv(C)
    except np.linalg.LinAlgError:
        return np.linalg.pinv(C, hermitian=True)


def _fuse_with(omega: np.ndarray, infos: np.ndarray, info_means: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    info = np.tensordot(omega, infos, axes=1)
    C = _inverse(info)
    return C @ (omega @ info_means), 0.5 * (C + C.T)


def covariance_intersection(means, covs) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Covariance intersection of ``k`` Gaussian estimates; returns ``(mean, cov, omega)``.

    ``omega`` minimises ``trace(C(omega))`` over the simplex: a bounded scalar search for two
    estimates (1/2 each when their covariances are equal, where every omega is optimal), SLSQP
    over the simplex (started at the centre, so the result does not depend on the order of the
    inputs beyond the optimiser's tolerance) for more.
    """
    means = np.asarray(means, dtype=float)
    covs = np.asarray([_conditioned(C) for C in covs], dtype=float)
    k = len(means)
    if k == 0:
        raise ValueError("covariance intersection needs at least one estimate")
    infos = np.stack([_inverse(C) for C in covs])
    info_means = np.einsum("kij,kj->ki", infos, means)
    if k == 1:
        omega = np.ones(1)
    elif k == 2 and np.array_equal(infos[0], infos[1]):
        # equal covariances: every omega gives the same covariance and trace; the symmetric
        # choice, so that the fused mean is the midpoint whatever the order (the search below
        # stopped at an end of its flat objective and took the second estimate's mean)
        omega = np.array([0.5, 0.5])
    elif k == 2:
        def trace2(w: float) -> float:
            return float(np.trace(_inverse(w * infos[0] + (1 - w) * infos[1])))

        res = minimize_scalar(trace2, bounds=(0.0, 1.0), method="bounded", options={"xatol": 1e-10})
        w = float(res.x)
        # the bounded search never evaluates the end points themselves
        candidates = [(trace2(w), w), (trace2(0.0), 0.0), (trace2(1.0), 1.0)]
        w = min(candidates)[1]
        omega = np.array([w, 1.0 - w])
    else:
        def trace_k(w: np.ndarray) -> float:
            return float(np.trace(_inverse(np.tensordot(w, infos, axes=1))))

        with threaded_blas():
            res = minimize(
                trace_k,
                np.full(k, 1.0 / k),
                method="SLSQP",
                bounds=[(0.0, 1.0)] * k,
                constraints=[{"type": "eq", "fun": lambda w: np.sum(w) - 1.0}],
                options={"ftol": 1e-12, "maxiter": 200},
            )
        omega = np.clip(res.x, 0.0, None)
        omega /= omega.sum()
    mean, cov = _fuse_with(omega, infos, info_means)
    return mean, cov, omega


def _odds(e: np.ndarray) -> np.ndarray:
    e = np.clip(np.asarray(e, dtype=float), 1e-12, 1 - 1e-12)
    return e / (1 - e)


def fused_existence(posterior, predicted=None, rule: str = "mean") -> float:
    """The team's existence probability.

    ``mean`` (the paper): e_hat = mean{e^j}.
    ``evidence`` (ours): every agent's update turned its predicted existence into its
    posterior by a likelihood ratio, odds(e^j) / odds(e^j_{t|t-1}); scans of different agents
    are independent given the target, so the team's posterior odds are the common prior odds
    (the mean predicted existence) times the product of those ratios. Agreeing misses or
    detections of several agents then count several times, as in a centralised filter.
    """
    post = np.asarray(posterior, dtype=float)
    if rule == "mean":
        return float(np.mean(post))
    if rule != "evidence":
        raise ValueError(f"unknown existence fusion rule {rule!r}")
    pred = np.asarray(predicted, dtype=float)
    log_odds = np.log(_odds(np.mean(pred))) + np.sum(np.log(_odds(post)) - np.log(_odds(pred)))
    return float(1.0 / (1.0 + np.exp(-np.clip(log_odds, -700, 700))))


def fused_visible(predicted, log_evidence, visibility) -> tuple[float, float]:
    """Evidence fusion with a hidden-target mode (ours): the target is hidden from every agent or
    from none, so the agents' scans are independent given the target *and* its visibility. With
    nu the mean predicted P(visible) and V_j = sum_i w_i L_i agent j's evidence were the target
    visible, the team's likelihood ratio is nu prod_j V_j + (1 - nu): agreeing misses count
    several times against a visible target, but once against a hidden one. Returns (e_hat,
    P(visible | exists))."""
    nu = float(np.mean(visibility))
    log_V = float(np.sum(log_evidence))
    prior = np.log(_odds(np.mean(np.asarray(predicted, dtype=float))))
    log_ratio = float(mix_visibility(np.array([log_V]), nu)[0])  # one agent's mixing, on the team's evidence
    visible = posterior_visibility(nu, log_V)
    log_odds = prior + log_ratio
    return float(1.0 / (1.0 + np.exp(-np.clip(log_odds, -700, 700)))), visible


RULES = ("mean", "evidence")


def fuse(estimates: list[Estimate], predicted: list[float] | None = None, rule: str = "mean",
         log_evidence: list[float] | None = None, visibility: list[float] | None = None) -> FusedEstimate:
    """The team's estimate: fused existence (:func:`fused_existence`), and the CI of the agents
    with e^j > 0.5. ``predicted`` holds the agents' e^j_{t|t-1}, needed by rule ``evidence``;
    with a hidden-target mode ``log_evidence`` and ``visibility`` hold each agent's log V_j and
    predicted P(visible) (:func:`fused_visible`).

    Checks its arguments first (the README's pieces used alone): existences and probabilities
    in [0, 1], means finite vectors of one length d, covariances finite, symmetric and positive
    semi-definite (d, d), one entry per estimate in each list, a known rule. The engine, whose
    estimates are built by the filters, calls :func:`fuse_unchecked`; both give the same result."""
    _check_fuse(estimates, predicted, rule, log_evidence, visibility)
    return fuse_unchecked(estimates, predicted, rule, log_evidence, visibility)


def _check_fuse(estimates, predicted, rule, log_evidence, visibility) -> None:
    if not isinstance(rule, str) or rule not in RULES:
        raise ValueError(f"rule: must be one of {', '.join(RULES)}, got {rule!r:.40}")
    try:
        estimates = list(estimates)
    except TypeError:
        raise TypeError(f"estimates: expected a list of Estimate, got {type(estimates).__name__}") from None
    if not estimates:
        raise ValueError("estimates: fuse needs at least one estimate")
    d = None
    for j, est in enumerate(estimates):
        if not all(hasattr(est, k) for k in ("existence", "mean", "cov")):
            raise TypeError(f"estimates[{j}]: expected an Estimate (existence, mean, cov), got {type(est).__name__}")
        real(f"estimates[{j}].existence", est.existence, 0.0, 1.0)
        mean = vector(f"estimates[{j}].mean", est.mean, d)
        if d is None:
            d = len(mean)
            if d == 0:
                raise ValueError(f"estimates[{j}].mean: expected at least one entry, got none")
        covariance(f"estimates[{j}].cov", est.cov, d)
    n = len(estimates)
    if rule == "evidence" and predicted is None:
        raise ValueError("predicted: rule 'evidence' needs every agent's predicted existence")
    for name, values, low, high in (("predicted", predicted, 0.0, 1.0), ("visibility", visibility, 0.0, 1.0),
                                    ("log_evidence", log_evidence, -math.inf, math.inf)):
        if values is None:
            continue
        a = vector(name, values, None) if name != "log_evidence" else _log_evidence(values)
        if len(a) != n:
            raise ValueError(f"{name}: expected one entry per estimate ({n}), got {len(a)}")
        if np.any((a < low) | (a > high)):
            raise ValueError(f"{name}: must lie in [{low:g}, {high:g}], got {a.tolist()!r:.60}")
    if (log_evidence is None) != (visibility is None):
        raise ValueError("log_evidence, visibility: give both (a hidden-target mode) or neither")


def _log_evidence(values) -> np.ndarray:
    """log V_j: numbers below +inf (-inf: a scan no particle could have made)."""
    a = numeric("log_evidence", values)
    if a.ndim != 1 or np.any(np.isnan(a)) or np.any(a == np.inf):
        raise ValueError(f"log_evidence: expected a vector of numbers below +inf, got {np.asarray(values).tolist()!r:.60}")
    return a


def fuse_unchecked(estimates: list[Estimate], predicted: list[float] | None = None, rule: str = "mean",
                   log_evidence: list[float] | None = None, visibility: list[float] | None = None) -> FusedEstimate:
    """:func:`fuse` without the checks of its arguments: the engine's, on the filters' estimates."""
    if not estimates:
        raise ValueError("fuse needs at least one estimate")
    visible = None
    if visibility is not None and rule == "evidence":
        existence, visible = fused_visible(predicted, log_evidence, visibility)
    else:  # under the paper's mean rule every agent keeps its own P(visible)
        existence = fused_existence([est.existence for est in estimates], predicted, rule)
    weights = np.zeros(len(estimates))
    sensing = [j for j, est in enumerate(estimates) if est.existence > CONFIRM]
    if not sensing:
        return FusedEstimate(existence, None, None, weights, visible)
    mean, cov, omega = covariance_intersection(
        [estimates[j].mean for j in sensing], [estimates[j].cov for j in sensing]
    )
    weights[sensing] = omega
    return FusedEstimate(existence, mean, cov, weights, visible)
