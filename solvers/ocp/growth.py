"""How much the dynamics amplify an error along an answer, and so which re-flight can verify it (issue 35 item 5).

An error ``d`` in the state at ``s`` is carried, to first order, to ``Phi(t, s) d`` by the state
transition matrix of the dynamics linearised along the answer (``A(t) = df/dx`` at its nodes).  Its
growth exponent is estimated from the frozen-time eigenvalues: ``G = int max(0, max Re eig A(t)) dt``
over the phase (the trapezoid over the nodes).  ``x' = 2x + u`` over 20 s gives ``G = 40``, an
amplification ``e^40 = 2.4e17``; Betts' Alp rider (eigenvalues -10, -2, -8 and +2) the same; a
stable system 0.  Eigenvalues rather than a product of step norms: a stable but non-normal system has
step norms above 1 whose product would flag it although its errors decay.

The re-flight from ``t0`` (:func:`solvers.ocp.verify.verify`) can only agree with an answer when it
would agree with an exact one.  An exact answer's nodes still carry :data:`NOISE` (IPOPT's ``tol``
on the scaled defect rows, 1e-8; DOP853's ``rtol`` of 1e-10 is below it), which the flight amplifies
by ``e^G``: past ``e^G * NOISE > agreement`` the flight from ``t0`` departs from any answer, right
or wrong, and neither a finer grid (terminal rounds) nor tighter limits (limit rounds) can bring it
back.  Such an answer is verified interval by interval (:data:`INTERVALS`): each interval re-flown
from its own first node with the answer's controls, the defect at its end held to the agreement
tolerance, the path limits checked on each interval's dense grid.  Below that the flight from
``t0`` (:data:`FROM_T0`) stays the check, unchanged.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

FROM_T0 = "from_t0"
INTERVALS = "interval_by_interval"
NOISE = 1e-8          # what an exact answer's scaled nodes carry: IPOPT's tol on the defect rows
# Below a thousandfold growth the flight from t0 stays the check whatever the agreement: an accuracy asked
# below the NLP's own tolerance (1e-9) is not the dynamics' doing, and there the flight from t0 is the
# stricter of the two checks.
MIN_EXPONENT = math.log(1e3)


@dataclass(frozen=True)
class Growth:
    """The growth exponent of one phase's answer and the verification mode it calls for."""

    exponent: float                 # G: ln of the estimated amplification over the phase
    max_real_eigenvalue: float      # the largest real part of df/dx's eigenvalues at any node (1/s)
    duration_s: float
    agreement: float                # the scaled agreement the re-flight is held to

    @property
    def threshold(self) -> float:
        """The exponent past which even an exact answer's re-flight from t0 departs by more than the agreement
        (at least :data:`MIN_EXPONENT`)."""
        return max(math.log(self.agreement / NOISE), MIN_EXPONENT)

    @property
    def mode(self) -> str:
        return INTERVALS if self.exponent > self.threshold else FROM_T0

    def reason(self) -> str:
        amp = _amplification_words(self.exponent)
        if self.mode == INTERVALS:
            return (f"the dynamics amplify errors by about {amp} over the phase (largest real part of the "
                    f"linearised dynamics' eigenvalues {self.max_real_eigenvalue:.3g} 1/s over "
                    f"{self.duration_s:.4g} s): the NLP's tolerance {NOISE:g} on the nodes would grow past "
                    f"the agreement {self.agreement:g} in a flight from t0 whatever the answer, so each interval "
                    "is re-flown from its own first node")
        return (f"the dynamics amplify errors by at most about {amp} over the phase, which keeps the NLP's "
                f"tolerance {NOISE:g} on the nodes within the agreement {self.agreement:g}: one flight from t0")

    def as_dict(self) -> dict:
        return {"exponent": self.exponent,
                "amplification": math.exp(self.exponent) if self.exponent < 700.0 else None,
                "max_real_eigenvalue": self.max_real_eigenvalue, "duration_s": self.duration_s,
                "threshold_exponent": self.threshold}


def _amplification_words(g: float) -> str:
    return f"e^{g:.3g} = {math.exp(g):.2g}" if g < 700.0 else f"e^{g:.3g}"


def jacobian_function(fns):
    """``(t, x, u, theta, c, t0, tf) -> df/dx`` of the phase's dynamics (the states' rows only)."""
    import casadi as ca

    t, x, u = ca.SX.sym("t"), ca.SX.sym("x", fns.nx), ca.SX.sym("u", fns.nu)
    theta, c = ca.SX.sym("theta", fns.ntheta), ca.SX.sym("c", fns.nc)
    t0, tf = ca.SX.sym("t0"), ca.SX.sym("tf")
    f = fns.rhs(t, x, u, theta, c, t0, tf)[:fns.nx]
    return ca.Function("ocp_dfdx", [t, x, u, theta, c, t0, tf], [ca.jacobian(f, x)])


def growth(*, fns, t_nodes: np.ndarray, X: np.ndarray, U: np.ndarray, theta, c, t0: float, tf: float,
           agreement: float) -> Growth:
    """The growth of phase ``fns``'s answer (nodes ``t_nodes``, states ``X``, controls ``U`` there)."""
    n = t_nodes.size
    jac = jacobian_function(fns).map(n)
    flat = np.asarray(jac(t_nodes[None, :], X, U if U.size else np.zeros((0, n)), np.asarray(theta, float),
                          np.asarray(c, float), t0, tf))
    nx = fns.nx
    rates = np.empty(n)
    for j in range(n):
        a = flat[:, j * nx:(j + 1) * nx]
        rates[j] = float(np.linalg.eigvals(a).real.max()) if np.all(np.isfinite(a)) else math.inf
    positive = np.maximum(rates, 0.0)
    dt = np.diff(t_nodes)
    g = float(np.sum(0.5 * (positive[1:] + positive[:-1]) * dt)) if n > 1 else 0.0
    return Growth(exponent=g if math.isfinite(g) else math.inf, max_real_eigenvalue=float(rates.max()),
                  duration_s=float(tf - t0), agreement=float(agreement))
