"""``uncertainty`` and ``robust`` of an ``ocp`` problem (``shared/specs/ocp.md``, "Robust design"): parsed and
checked at the door.

``uncertainty.parameters`` names declared constants, each normal (``sigma``, ``mean`` defaulting to the
declared value) or uniform (``lower`` < ``upper``); ``uncertainty.initial`` names states with a normal
``sigma`` on their initial value.  ``robust`` holds ``k`` (default 3), the objective's statistic
(``mean_minus_k_sigma`` for a maximum, ``mean_plus_k_sigma`` for a minimum by default, or ``mean``), the
names of the path and boundary constraints held at mean +- k sigma, and the Monte Carlo's ``samples``.
Every refusal is an :class:`solvers.ocp.expressions.OcpInputError` naming the field: an unknown constant
or state (with the closest declared name), a sigma that is not positive, bounds out of order, an uncertain
constant that no expression of the problem uses (its uncertainty could not change anything), a constraint
name the problem does not have.  Standard library only (the API process parses with it).
"""
from __future__ import annotations

import math

from solvers.ocp.expressions import OcpInputError, closest, names_used
from solvers.ocp.readers import number_at, object_at, unknown_fields
from solvers.ocp.robust.model import (
    DEFAULT_K,
    DEFAULT_ROUNDS,
    DEFAULT_SAMPLES,
    MAX_ROUNDS,
    InitialSigma,
    RobustSpec,
    UncertainConstant,
)

UNCERTAINTY_FIELDS = ("parameters", "initial")
NORMAL_FIELDS = ("distribution", "sigma", "mean")
UNIFORM_FIELDS = ("distribution", "lower", "upper")
INITIAL_FIELDS = ("sigma",)
ROBUST_FIELDS = ("k", "objective", "constraints", "monte_carlo")
MONTE_CARLO_FIELDS = ("samples", "rounds", "sigma_factor")
STATISTICS = ("mean_minus_k_sigma", "mean", "mean_plus_k_sigma")
MIN_SAMPLES = 100
MAX_K = 10.0


def parse_robust(params: dict, *, constants: dict[str, float], states: tuple[str, ...], trees: list,
                 path_names: tuple[str, ...], boundary_names: tuple[str, ...], sense: str,
                 max_samples: int) -> RobustSpec | None:
    """``params.uncertainty`` and ``params.robust`` (None when neither is given); ``trees``: every
    expression tree of the problem (dynamics, expressions, constraints, objective)."""
    raw_u, raw_r = params.get("uncertainty"), params.get("robust")
    if raw_u is None and raw_r is None:
        return None
    P = "params.uncertainty"
    if raw_u is None:
        raise OcpInputError(P, "robust design needs the uncertainty: {\"parameters\": {CONSTANT: {...}}, "
                               "\"initial\"?: {STATE: {\"sigma\"}}}")
    unc = {k: v for k, v in object_at(raw_u, P).items() if v is not None}
    unknown_fields(unc, UNCERTAINTY_FIELDS, P)
    used = set().union(*[names_used(t) for t in trees]) if trees else set()
    parameters = tuple(_constant(name, spec, f"{P}.parameters.{name}", constants, used)
                       for name, spec in object_at(unc.get("parameters"), f"{P}.parameters").items())
    initial = []
    for name, spec in object_at(unc.get("initial"), f"{P}.initial").items():
        ip = f"{P}.initial.{name}"
        if name not in states:
            near = closest(name, states)
            raise OcpInputError(ip, f"'{name}' is not a declared state" + (f" (did you mean '{near}'?)" if near else ""))
        spec = {k: v for k, v in object_at(spec, ip).items() if v is not None}
        unknown_fields(spec, INITIAL_FIELDS, ip)
        initial.append(InitialSigma(name, _positive(spec.get("sigma"), f"{ip}.sigma")))
    if not parameters and not initial:
        raise OcpInputError(P, "name at least one uncertain constant (parameters) or initial state (initial)")
    R = "params.robust"
    rob = {k: v for k, v in object_at(raw_r, R).items() if v is not None}
    unknown_fields(rob, ROBUST_FIELDS, R)
    k = number_at(rob.get("k"), f"{R}.k")
    k = DEFAULT_K if k is None else k
    if not 0.0 <= k <= MAX_K:
        raise OcpInputError(f"{R}.k", f"k = {k:g} is outside [0, {MAX_K:g}]")
    statistic = rob.get("objective", "mean_minus_k_sigma" if sense == "maximize" else "mean_plus_k_sigma")
    if statistic not in STATISTICS:
        raise OcpInputError(f"{R}.objective", f"'{statistic}' is not one of {', '.join(STATISTICS)}")
    names = rob.get("constraints") or []
    if not isinstance(names, list):
        raise OcpInputError(f"{R}.constraints", "a list of names of path and boundary constraints")
    declared = path_names + boundary_names
    for i, nm in enumerate(names):
        if nm not in declared:
            near = closest(str(nm), declared)
            raise OcpInputError(f"{R}.constraints.{i}", f"'{nm}' is not the name of a path or boundary constraint"
                                + (f" (did you mean '{near}'?)" if near else f" (declared: {', '.join(declared) or 'none'})"))
    if len(set(names)) != len(names):
        raise OcpInputError(f"{R}.constraints", "a constraint is named twice")
    mc = {k: v for k, v in object_at(rob.get("monte_carlo"), f"{R}.monte_carlo").items() if v is not None}
    unknown_fields(mc, MONTE_CARLO_FIELDS, f"{R}.monte_carlo")
    samples = mc.get("samples", DEFAULT_SAMPLES)
    if not isinstance(samples, int) or isinstance(samples, bool) or not MIN_SAMPLES <= samples <= max_samples:
        raise OcpInputError(f"{R}.monte_carlo.samples", f"an integer in [{MIN_SAMPLES}, {max_samples}] "
                                                       f"(the limit max_monte_carlo_samples={max_samples})")
    rounds = mc.get("rounds", DEFAULT_ROUNDS)
    if not isinstance(rounds, int) or isinstance(rounds, bool) or not 0 <= rounds <= MAX_ROUNDS:
        raise OcpInputError(f"{R}.monte_carlo.rounds", f"an integer in [0, {MAX_ROUNDS}]")
    factor = number_at(mc.get("sigma_factor"), f"{R}.monte_carlo.sigma_factor")
    factor = 1.0 if factor is None else factor
    if not 0.0 < factor <= 10.0:
        raise OcpInputError(f"{R}.monte_carlo.sigma_factor", f"{factor:g} is outside (0, 10]")
    return RobustSpec(parameters=parameters, initial=tuple(initial), k=float(k), objective=statistic,
                      constraints=tuple(names), samples=samples, rounds=rounds, sigma_factor=factor)


def _positive(value, path: str) -> float:
    v = number_at(value, path, optional=False)
    if not v > 0:
        raise OcpInputError(path, f"a sigma must be positive, not {v:g}")
    return v


def _constant(name: str, spec, path: str, constants: dict[str, float], used: set[str]) -> UncertainConstant:
    if name not in constants:
        near = closest(name, tuple(constants))
        raise OcpInputError(path, f"'{name}' is not a declared constant"
                            + (f" (did you mean '{near}'?)" if near else " (uncertain parameters are constants)"))
    if name not in used:
        raise OcpInputError(path, f"no expression uses the constant '{name}': its uncertainty changes nothing")
    spec = {k: v for k, v in object_at(spec, path).items() if v is not None}   # null: not given
    law = spec.get("distribution")
    if law == "normal":
        unknown_fields(spec, NORMAL_FIELDS, path)
        sigma = _positive(spec.get("sigma"), f"{path}.sigma")
        mean = number_at(spec.get("mean"), f"{path}.mean")
        return UncertainConstant(name, "normal", constants[name] if mean is None else mean, sigma)
    if law == "uniform":
        unknown_fields(spec, UNIFORM_FIELDS, path)
        lo = number_at(spec.get("lower"), f"{path}.lower", optional=False)
        hi = number_at(spec.get("upper"), f"{path}.upper", optional=False)
        if not lo < hi:
            raise OcpInputError(path, f"lower ({lo:g}) must be below upper ({hi:g})")
        return UncertainConstant(name, "uniform", 0.5 * (lo + hi), (hi - lo) / math.sqrt(12.0), lo, hi)
    raise OcpInputError(f"{path}.distribution", f"'{law}' is neither 'normal' nor 'uniform'")
