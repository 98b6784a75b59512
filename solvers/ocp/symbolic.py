"""Expression trees of :mod:`solvers.ocp.expressions` -> CasADi SX, and the problem's SX functions.

Tables become CasADi B-spline ``interpolant``s (cubic where an axis has 4 or more points, lower
degree below that) through :func:`solvers.models.tables.spline`, so the NLP and every numpy-side
check evaluate the same spline; inputs are clamped to the table's range (a cubic extrapolation
can turn over).  The spec stores 2-D values row-major (first axis slowest); CasADi wants the
first axis fastest, hence the transpose.

:func:`phase_functions` turns one phase into four SX functions of the same arguments
``(t, x, u, theta, c)`` (``theta``: the static decision parameters, ``c``: the constants, NLP
parameters so that a study over a constant reuses the build): the right-hand side with the
Lagrange integrand appended, the path constraints, the named expressions, and the event
function of ``(t0, tf, x0, xf, u0, uf, theta, c)`` holding the boundary constraints and the
Mayer term.
"""
from __future__ import annotations

import threading
from dataclasses import dataclass
from functools import lru_cache

import casadi as ca
import numpy as np

from solvers.models.tables import clamp
from solvers.ocp.expressions import BinOp, Boundary, EventTime, Expr, Name, Neg, Num
from solvers.ocp.problem import PhaseProblem, TableDecl

_UNARY = {
    "sin": ca.sin, "cos": ca.cos, "tan": ca.tan, "asin": ca.asin, "acos": ca.acos, "atan": ca.atan,
    "sinh": ca.sinh, "cosh": ca.cosh, "tanh": ca.tanh, "exp": ca.exp, "log": ca.log,
    "log10": ca.log10, "sqrt": ca.sqrt, "abs": ca.fabs, "sign": ca.sign,
}


@lru_cache(maxsize=64)
def table_function(table: TableDecl) -> ca.Function:
    """The table as a CasADi B-spline of its 1 or 2 inputs (values given row-major)."""
    shape = tuple(len(a) for a in table.axes)
    values = np.asarray(table.values, float).reshape(shape).ravel(order="F")
    degree = [min(3, n - 1) for n in shape]
    return ca.interpolant(f"table_{table.name}", "bspline", [list(a) for a in table.axes],
                          values.tolist(), {"degree": degree})


def to_sx(node: Expr, env: dict, tables: dict[str, TableDecl], boundary: dict | None = None):
    """The CasADi expression of a tree: ``env`` name -> symbol, ``boundary`` (which, name) -> symbol."""
    if isinstance(node, Num):
        return ca.SX(node.value)
    if isinstance(node, Name):
        return env[node.name]
    if isinstance(node, (Boundary, EventTime)):
        if boundary is None:  # the parser refuses it
            raise ValueError("initial(), final(), t0() or tf() outside a boundary expression")
        if isinstance(node, Boundary):      # a multi-phase event names its phase
            return boundary[(node.which, node.name, node.phase) if node.phase else (node.which, node.name)]
        return boundary[(node.which, node.phase)]
    if isinstance(node, Neg):
        return -to_sx(node.operand, env, tables, boundary)
    if isinstance(node, BinOp):
        a = to_sx(node.left, env, tables, boundary)
        if node.op == "**" and isinstance(node.right, Num) and float(node.right.value).is_integer():
            return ca.constpow(a, node.right.value)
        b = to_sx(node.right, env, tables, boundary)
        return {"+": a + b, "-": a - b, "*": a * b, "/": a / b}[node.op] if node.op != "**" else a ** b
    args = [to_sx(a, env, tables, boundary) for a in node.args]
    if node.table:
        tb = tables[node.func]
        args = [clamp(x, ax[0], ax[-1], ca) for x, ax in zip(args, tb.axes)]
        return table_function(tb)(ca.vertcat(*args))
    if node.func in _UNARY:
        return _UNARY[node.func](args[0])
    if node.func == "atan2":
        return ca.atan2(args[0], args[1])
    if node.func == "hypot":
        return ca.sqrt(args[0] ** 2 + args[1] ** 2)
    fold = ca.fmin if node.func == "min" else ca.fmax
    out = args[0]
    for a in args[1:]:
        out = fold(out, a)
    return out


@dataclass(frozen=True)
class PhaseFunctions:
    """The phase's SX functions (module docstring); sizes for the transcriptions."""

    rhs: ca.Function          # (t, x, u, theta, c) -> [xdot; integrand] (nx + nq)
    path: ca.Function         # (t, x, u, theta, c) -> path constraint values (npath)
    named: ca.Function        # (t, x, u, theta, c) -> the named expressions (nexpr)
    events: ca.Function       # (t0, tf, x0, xf, u0, uf, theta, c) -> (boundary values, mayer)
    nx: int
    nu: int
    ntheta: int
    nc: int
    nq: int                   # 1 with a Lagrange integrand, else 0
    npath: int
    nboundary: int


def phase_functions(problem: PhaseProblem) -> PhaseFunctions:
    ph = problem.phase
    nx, nu = len(ph.states), len(ph.controls)
    ntheta, nc = len(problem.parameters), len(problem.constants)
    t, t0, tf = ca.SX.sym("t"), ca.SX.sym("t0"), ca.SX.sym("tf")
    x, u = ca.SX.sym("x", nx), ca.SX.sym("u", nu)
    theta, c = ca.SX.sym("theta", ntheta), ca.SX.sym("c", nc)
    tables = {tb.name: tb for tb in problem.tables}
    common = {"t0": t0, "tf": tf}
    common.update({n: c[i] for i, (n, _) in enumerate(problem.constants)})
    common.update({p.name: theta[i] for i, p in enumerate(problem.parameters)})
    env = {**common, "t": t}
    env.update({s.name: x[i] for i, s in enumerate(ph.states)})
    env.update({k.name: u[i] for i, k in enumerate(ph.controls)})
    named = []
    for name, tree in ph.expressions:
        env[name] = to_sx(tree, env, tables)
        named.append(env[name])
    xdot = [to_sx(e, env, tables) for e in ph.dynamics]
    nq = 0
    if problem.objective.integrand is not None:
        xdot.append(to_sx(problem.objective.integrand, env, tables))
        nq = 1
    path = [to_sx(cn.expr, env, tables) for cn in ph.path]
    # t0 and tf are inputs of every function: along the phase they enter through t and, where an
    # expression names them, directly.
    args = [t, x, u, theta, c, t0, tf]
    names = ["t", "x", "u", "theta", "c", "t0", "tf"]
    rhs = ca.Function("ocp_rhs", args, [ca.vertcat(*xdot)], names, ["f"])
    pathf = ca.Function("ocp_path", args, [ca.vertcat(*path) if path else ca.SX.zeros(0)], names, ["g"])
    namedf = ca.Function("ocp_named", args, [ca.vertcat(*named) if named else ca.SX.zeros(0)], names, ["e"])

    x0, xf = ca.SX.sym("x0", nx), ca.SX.sym("xf", nx)
    u0, uf = ca.SX.sym("u0", nu), ca.SX.sym("uf", nu)
    bnd = {("initial", s.name): x0[i] for i, s in enumerate(ph.states)}
    bnd.update({("final", s.name): xf[i] for i, s in enumerate(ph.states)})
    bnd.update({("initial", k.name): u0[i] for i, k in enumerate(ph.controls)})
    bnd.update({("final", k.name): uf[i] for i, k in enumerate(ph.controls)})
    ev = [to_sx(cn.expr, common, tables, bnd) for cn in ph.boundary]
    mayer = to_sx(problem.objective.expr, common, tables, bnd) if problem.objective.expr is not None else ca.SX(0)
    events = ca.Function("ocp_events", [t0, tf, x0, xf, u0, uf, theta, c],
                         [ca.vertcat(*ev) if ev else ca.SX.zeros(0), mayer],
                         ["t0", "tf", "x0", "xf", "u0", "uf", "theta", "c"], ["b", "mayer"])
    return PhaseFunctions(rhs=rhs, path=pathf, named=namedf, events=events, nx=nx, nu=nu,
                          ntheta=ntheta, nc=nc, nq=nq, npath=len(path), nboundary=len(ev))


_FUNCTIONS: dict[tuple, PhaseFunctions] = {}
_FUNCTIONS_LOCK = threading.Lock()


def functions_of(problem: PhaseProblem) -> PhaseFunctions:
    """The phase's SX functions, built once per structure (grid aside) in this process."""
    key = problem.structure()[:-1]          # the functions do not depend on the grid
    with _FUNCTIONS_LOCK:
        fns = _FUNCTIONS.get(key)
    if fns is None:
        fns = phase_functions(problem)
        with _FUNCTIONS_LOCK:
            if len(_FUNCTIONS) > 32:
                _FUNCTIONS.clear()
            _FUNCTIONS[key] = fns
    return fns


def reset_caches() -> None:
    """Forget the symbolic functions (benchmarks time a cold build with this and
    :func:`solvers.transcription.nlp.clear_cache`)."""
    with _FUNCTIONS_LOCK:
        _FUNCTIONS.clear()
    table_function.cache_clear()
