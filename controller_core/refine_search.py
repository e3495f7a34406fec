"""A node's rows searched on the bench until its features move by minus the patient's measured bias.

One linear step per round through a sensitivity measured on another leg cannot reach a target the rows only reach
together and non-linearly (the swing knee peak's timing: docs/results.md); a search on the bench can, when the bench
walks the patient's own leg. Per node, at the node's task:

1. walk the node's current rows: the bench's features ``f0`` (mean error against the model's targets per quantity,
   display units);
2. aim at ``f0 − bias``: each quantity the patient's strides support acting on moves by minus its measured bias, the
   others are held where they are (bias 0);
3. Levenberg–Marquardt in a trust region: the step solves (AᵀA + λ²I) u = −Aᵀr in parameters scaled by one round's step
   limit and residuals scaled by each quantity's tolerance; the Jacobian starts from the shipped sensitivity and is
   corrected after every walk by Broyden's rank-one update (the walk measured what the step did, on this leg);
   a walked candidate that lowers the cost is kept and λ halves, one that does not (or that the bench refuses: more
   falls, strides turned irregular, a quantity no longer found) leaves the rows where they were and λ doubles;
4. stop when every quantity is within half its tolerance of its aim, when the walks are spent, or when the trust
   region has shrunk below the rows' resolution.

Every candidate is clamped into the safety limits before it is walked (:func:`controller_core.refine._stepped`), and
the whole search stays within ``bound_steps`` round-step limits of the rows it began from (θe ±10°, k and b
×/÷1.5625 at the default two: what two rounds of the one-step refinement allowed), so a round's change is bounded and
shown. The walks are noisy (a 16 s walk's mean peak is uncertain by about ±0.5°): a candidate is kept only if it lowers
the cost, so noise can stop the search early but cannot walk it away from the aim.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from controller_core.refine_evidence import QUANTITIES
from controller_core.table import ParameterTable

TOLERANCES = np.array([q.tolerance for q in QUANTITIES])   # each quantity's, display unit


class NodeBench(Protocol):
    """The bench a search walks: a table at a task on the patient's leg (or the nominal one, said by ``leg``)."""

    leg: str

    def errors(self, table: ParameterTable, speed_mps: float, incline_deg: float) -> dict[str, object]:
        """``{"error": {quantity key: mean error or None}, "spread": {...}, "falls": int, "strides": int}``."""
        ...

    def worse(self, before: dict[str, object], after: dict[str, object]) -> str | None:
        """Why the walk ``after`` is not acceptable next to ``before`` (more falls, irregular strides), or None."""
        ...


class EnvelopeBench(Protocol):
    """A bench that walks one node's candidate rows inside an envelope, as the leg runs them."""

    def at_node(self, envelope: Any, index: int) -> NodeBench:
        ...


def feature_vector(walk: dict[str, object]) -> np.ndarray:
    """The walk's mean error per quantity of :data:`QUANTITIES` (NaN where not found)."""
    errors = walk["error"]
    assert isinstance(errors, dict)
    return np.array([math.nan if errors.get(q.key) is None else float(errors[q.key]) for q in QUANTITIES])


@dataclass(frozen=True)
class TrustRegionSearch:
    """Hyperparameters of the search (module docstring).

    Args:
        max_walks: walks per node, the walk of the current rows included.
        bound_steps: the most any value moves from the rows the search began from, in one round's step limits.
        damping: the first λ, in units of one step limit per tolerance.
        aim_fraction: the search stops once every quantity is within this fraction of its tolerance of its aim.
    """

    max_walks: int = 8
    bound_steps: float = 2.0
    damping: float = 1.0
    aim_fraction: float = 0.5

    def __post_init__(self) -> None:
        if not (isinstance(self.max_walks, int) and 2 <= self.max_walks <= 50):
            raise ValueError(f"max_walks must be a whole number from 2 to 50, got {self.max_walks!r}")
        for name in ("bound_steps", "damping", "aim_fraction"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be a positive finite number, got {v!r}")


@dataclass
class SearchTrace:
    """What a node's search did: walks made, the bench's features before and at the kept rows, the kept step
    (stepping units: deg or ln|value|) and the step asked of ``apply`` that made them, the corrected Jacobian and why
    candidates were refused."""

    walks: int = 0
    before: np.ndarray = field(default_factory=lambda: np.zeros(0))
    after: np.ndarray = field(default_factory=lambda: np.zeros(0))
    step: np.ndarray = field(default_factory=lambda: np.zeros(0))
    proposal: np.ndarray = field(default_factory=lambda: np.zeros(0))   # the step ``apply`` made the kept rows from
    jacobian: np.ndarray = field(default_factory=lambda: np.zeros(0))
    refused: list[str] = field(default_factory=list)
    stopped: str = ""

    def to_json(self) -> dict[str, object]:
        def vec(v: np.ndarray) -> dict[str, float | None]:
            return {q.key: None if not math.isfinite(x) else round(float(x), 3) for q, x in zip(QUANTITIES, v, strict=True)}

        return {"walks": self.walks, "bench_error_before": vec(self.before), "bench_error_after": vec(self.after),
                "refused": self.refused, "stopped": self.stopped}


def broyden(J: np.ndarray, dx: np.ndarray, df: np.ndarray) -> np.ndarray:
    """Broyden's rank-one correction of ``J`` (quantities × parameters) so that J·dx = df, on the rows where ``df`` is
    finite; the other rows stay as they were."""
    ok = np.isfinite(df)
    norm = float(dx @ dx)
    if norm == 0.0 or not ok.any():
        return J
    out = J.copy()
    out[ok] += np.outer(df[ok] - J[ok] @ dx, dx) / norm
    return out


def lm_step(J: np.ndarray, residual: np.ndarray, steps: np.ndarray, damping: float) -> np.ndarray:
    """The Levenberg–Marquardt step (stepping units) for ``residual`` (in tolerances, NaN rows left out) through
    ``J`` with the parameters scaled by ``steps``."""
    ok = np.isfinite(residual)
    A = J[ok] * steps[None, :] / TOLERANCES[ok, None]
    u = np.linalg.solve(A.T @ A + damping ** 2 * np.eye(steps.size), -A.T @ residual[ok])
    return u * steps


def search_rows(table: ParameterTable, bias: np.ndarray, J0: np.ndarray, steps: np.ndarray, resolution: np.ndarray,
                apply: Callable[[np.ndarray], tuple[ParameterTable, np.ndarray] | str], bench: NodeBench,
                task: tuple[float, float], settings: TrustRegionSearch,
                box: tuple[np.ndarray, np.ndarray] | None = None, aim: np.ndarray | None = None
                ) -> tuple[ParameterTable, SearchTrace]:
    """The search (module docstring) from ``table`` at ``task`` (speed m/s, incline deg).

    Args:
        bias: per quantity of :data:`QUANTITIES`, the patient's bias to remove (0: hold the quantity).
        J0: the starting sensitivity (quantities × parameters, per stepping unit).
        steps, resolution: per parameter, one round's step limit and the smallest change kept (stepping units).
        apply: a step (stepping units from ``table``) → (the table moved by it, clamped into the limits, and the step
            it actually took), or why no table.
        bench: walks a table at ``task``.
        box: per parameter, the lowest and highest step (stepping units) the rows may take besides the search's own
            bound: an envelope node's neighbours' values within the neighbour rule's steps, so that the rows the bench
            confirms are the rows the envelope keeps.
        aim: the features to reach (default: what ``table`` gives on the bench, minus ``bias``).
    Returns: the kept rows (``table`` itself when no candidate lowered the cost) and the trace.
    """
    trace = SearchTrace()
    base = bench.errors(table, *task)
    trace.walks = 1
    f0 = feature_vector(base)
    aim = f0 - bias if aim is None else np.where(np.isfinite(aim), aim, f0 - bias)
    trace.before, trace.after, trace.step, trace.jacobian = f0, f0, np.zeros(steps.size), J0.copy()

    def cost(f: np.ndarray) -> float:
        r = ((f - aim) / TOLERANCES)[np.isfinite(f0)]
        return math.inf if not np.all(np.isfinite(r)) else float(r @ r)

    best_table, best_f, best_cost, x = table, f0, cost(f0), np.zeros(steps.size)
    trace.proposal = x
    J, lam = J0.copy(), settings.damping
    low, high = -settings.bound_steps * steps, settings.bound_steps * steps
    if box is not None:
        low, high = np.minimum(np.maximum(low, box[0]), 0.0), np.maximum(np.minimum(high, box[1]), 0.0)
    while True:
        r = (best_f - aim) / TOLERANCES
        if np.all(np.abs(r[np.isfinite(r)]) <= settings.aim_fraction):
            trace.stopped = "every quantity within half its tolerance of its aim"
            break
        if trace.walks >= settings.max_walks:
            trace.stopped = f"{settings.max_walks} walks made"
            break
        proposal = np.clip(x + lm_step(J, r, steps, lam), low, high)
        proposal[np.abs(proposal) < resolution] = 0.0
        made = apply(proposal)
        if isinstance(made, str) or np.all(np.abs((actual := made[1]) - x) < resolution):
            if lam > 64.0 * settings.damping:
                trace.stopped = "the trust region shrank below the rows' resolution"
                break
            lam *= 4.0
            continue
        candidate = made[0]
        walk = bench.errors(candidate, *task)
        trace.walks += 1
        f = feature_vector(walk)
        J = broyden(J, actual - x, f - best_f)
        why = bench.worse(base, walk)
        if why is None and np.any(np.isfinite(f0) & ~np.isfinite(f)):
            why = "a quantity was no longer found on the bench's strides"
        c = cost(f) if why is None else math.inf
        if why is not None:
            trace.refused.append(why)
        if c < best_cost:
            best_table, best_f, best_cost, x, trace.proposal = candidate, f, c, actual, proposal
            lam = max(lam / 2.0, settings.damping / 4.0)
        else:
            lam *= 2.0
    trace.after, trace.step, trace.jacobian = best_f, x, J
    return best_table, trace
