"""The expression language of the ``ocp`` kind: user text -> a small immutable tree, never evaluated.

The grammar is Python's expression grammar cut down by an allow-list (``../shared/specs/ocp.md``,
"The expression language"): numbers, declared names, ``+ - * / **``, unary minus and plus,
parentheses, calls of the functions in :data:`FUNCTIONS` and of declared tables, and
``initial(name)`` / ``final(name)`` where the caller allows them (boundary and objective); in a
multi-phase problem's top-level events (``objective``, ``links``) ``initial(name, "phase")``,
``final(name, "phase")``, ``t0("phase")`` and ``tf("phase")``, where a string literal is allowed
as the phase argument of these four calls and nowhere else.
``ast.parse(mode="eval")`` gives the tree; every node type outside the allow-list is an
:class:`OcpInputError` naming the field path and the construct.  The text is never handed to
``eval``, ``exec``, ``compile`` to code objects or any parser that evaluates (as OpenMDAO's
``ExecComp`` and numexpr validate before they compile).

Resource guards, in the order they apply: the length of the text before parsing (the parser's
own cost grows with it), RecursionError/MemoryError from the parser (deep nesting), then the
number of tree nodes, counted iteratively before any recursive walk, so that the recursive
conversion below is bounded by the node limit.

Standard library only: the API process imports this module to validate a problem before storing it.
"""
from __future__ import annotations

import ast
import difflib
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import NoReturn, Union

# name -> (smallest, largest) number of arguments; None: no upper bound.
FUNCTIONS: dict[str, tuple[int, int | None]] = {
    **{f: (1, 1) for f in ("sin", "cos", "tan", "asin", "acos", "atan", "sinh", "cosh", "tanh",
                           "exp", "log", "log10", "sqrt", "abs", "sign")},
    "atan2": (2, 2), "hypot": (2, 2), "min": (2, None), "max": (2, None),
}
BOUNDARY_FUNCTIONS = ("initial", "final")
RESERVED = ("t", "t0", "tf", "pi", "initial", "final")
_BINOPS = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/", ast.Pow: "**"}


class OcpInputError(ValueError):
    """A problem that cannot be built: ``path`` is the field (``params.dynamics.v``), ``reason`` why."""

    def __init__(self, path: str, reason: str):
        super().__init__(f"{path}: {reason}")
        self.path = path
        self.reason = reason


# --- the tree ------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class Num:
    value: float


@dataclass(frozen=True, slots=True)
class Name:
    """A declared name, ``t``, ``t0``, ``tf`` or ``pi``; ``kind`` says which namespace it is in."""

    name: str
    kind: str


@dataclass(frozen=True, slots=True)
class Neg:
    operand: Expr


@dataclass(frozen=True, slots=True)
class BinOp:
    op: str             # one of + - * / **
    left: Expr
    right: Expr


@dataclass(frozen=True, slots=True)
class Call:
    """A function of :data:`FUNCTIONS` (``table=False``) or a declared table (``table=True``)."""

    func: str
    args: tuple
    table: bool = False


@dataclass(frozen=True, slots=True)
class Boundary:
    """``initial(name)`` or ``final(name)``: a state's (or control's) value at an end of the phase;
    ``initial(name, "phase")`` names the phase (multi-phase events)."""

    which: str          # "initial" | "final"
    name: str
    kind: str           # "state" | "control"
    phase: str = ""     # "" in a single phase


@dataclass(frozen=True, slots=True)
class EventTime:
    """``t0("phase")`` or ``tf("phase")``: a phase's initial or final time (multi-phase events)."""

    which: str          # "t0" | "tf"
    phase: str


Expr = Union[Num, Name, Neg, BinOp, Call, Boundary, EventTime]  # a runtime alias (isinstance, get_args)


def walk(node: Expr):
    """Every node of a tree, iteratively (parents before children)."""
    stack = [node]
    while stack:
        n = stack.pop()
        yield n
        if isinstance(n, Neg):
            stack.append(n.operand)
        elif isinstance(n, BinOp):
            stack += [n.right, n.left]
        elif isinstance(n, Call):
            stack += reversed(n.args)


def names_used(node: Expr) -> set[str]:
    return {n.name for n in walk(node) if isinstance(n, (Name, Boundary))}


def to_text(node: Expr) -> str:
    """Canonical text of a tree (fully parenthesised): a cache key and a readable form."""
    if isinstance(node, Num):
        return repr(node.value)
    if isinstance(node, Name):
        return node.name
    if isinstance(node, Boundary):
        return f'{node.which}({node.name},"{node.phase}")' if node.phase else f"{node.which}({node.name})"
    if isinstance(node, EventTime):
        return f'{node.which}("{node.phase}")'
    if isinstance(node, Neg):
        return f"(-{to_text(node.operand)})"
    if isinstance(node, BinOp):
        return f"({to_text(node.left)}{node.op}{to_text(node.right)})"
    return f"{node.func}({','.join(to_text(a) for a in node.args)})"


# --- the parser ----------------------------------------------------------------------------------
@dataclass(frozen=True)
class Scope:
    """What an expression may refer to: ``names`` name -> kind (``constant``, ``state``, ``control``,
    ``parameter``, ``expression``, ``time``), ``tables`` name -> dimension, ``boundary``: whether
    ``initial()``/``final()`` may appear (and bare states and controls may not), ``where``: words for
    the messages (``"dynamics"``), ``phases``: in a multi-phase problem's top-level events, phase
    name -> (its state and control names -> kind): the event functions then name the phase."""

    names: Mapping[str, str]
    tables: Mapping[str, int]
    boundary: bool = False
    where: str = "this field"
    phases: Mapping[str, Mapping[str, str]] | None = None


def closest(name: str, candidates) -> str | None:
    match = difflib.get_close_matches(name, list(candidates), n=1, cutoff=0.0)
    return match[0] if match else None


def parse_expression(text, *, path: str, scope: Scope, max_chars: int = 2000,
                     max_nodes: int = 400) -> Expr:
    """Parse and validate one expression; raises :class:`OcpInputError` for anything outside the language."""
    if isinstance(text, (bool, int, float)):
        text = repr(float(text))      # a bare JSON number is an expression too
    if not isinstance(text, str):
        raise OcpInputError(path, f"an expression must be a string, not {type(text).__name__}")
    if len(text) > max_chars:
        raise OcpInputError(path, f"expression of {len(text)} characters exceeds the limit "
                                  f"max_expression_chars={max_chars}")
    if not text.strip():
        raise OcpInputError(path, "empty expression")
    try:
        tree = ast.parse(text.strip(), mode="eval")
    except SyntaxError as e:
        col = e.offset if e.offset is not None else 0
        raise OcpInputError(path, f"syntax error at column {col}: {e.msg}") from None
    except (RecursionError, MemoryError):
        raise OcpInputError(path, "expression nested too deeply") from None
    except ValueError as e:             # e.g. a NUL character in the text
        raise OcpInputError(path, f"cannot parse: {e}") from None
    for count, _ in enumerate(ast.walk(tree), 1):   # iterative: safe on any tree the parser produced
        if count > max_nodes:
            raise OcpInputError(path, f"expression has more than {max_nodes} nodes "
                                      f"(limit max_expression_nodes={max_nodes})")
    return _Converter(path, scope).convert(tree.body)


class _Converter:
    def __init__(self, path: str, scope: Scope):
        self.path, self.scope = path, scope

    def fail(self, node: ast.AST, reason: str) -> NoReturn:
        col = getattr(node, "col_offset", None)
        where = f" (column {col + 1})" if col is not None else ""
        raise OcpInputError(self.path, reason + where)

    def convert(self, node: ast.AST) -> Expr:
        if isinstance(node, ast.Constant):
            v = node.value
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                self.fail(node, f"only numbers are allowed, not {type(v).__name__} {v!r:.40}")
            try:
                f = float(v)
            except OverflowError:
                f = math.inf
            if not math.isfinite(f):
                self.fail(node, f"number {str(v)[:40]} is not finite")
            return Num(f)
        if isinstance(node, ast.Name):
            return self.name(node)
        if isinstance(node, ast.UnaryOp):
            if isinstance(node.op, ast.USub):
                return Neg(self.convert(node.operand))
            if isinstance(node.op, ast.UAdd):
                return self.convert(node.operand)
            self.fail(node, f"forbidden operator {type(node.op).__name__} (only unary - and +)")
        if isinstance(node, ast.BinOp):
            op = _BINOPS.get(type(node.op))
            if op is None:
                self.fail(node, f"forbidden operator {type(node.op).__name__} (only + - * / **)")
            return BinOp(op, self.convert(node.left), self.convert(node.right))
        if isinstance(node, ast.Call):
            return self.call(node)
        self.fail(node, f"forbidden construct {type(node).__name__}: only numbers, names, "
                        "+ - * / **, parentheses and function calls are allowed")

    def name(self, node: ast.Name) -> Expr:
        nm, scope = node.id, self.scope
        if nm == "pi":
            return Num(math.pi)
        kind = scope.names.get(nm)
        if kind is None and scope.phases is not None:
            if nm in ("t0", "tf"):
                self.fail(node, f"several phases: write {nm}(\"phase\") naming the phase")
            owner = next((ph for ph, decl in scope.phases.items() if nm in decl), None)
            if owner is not None:
                self.fail(node, f"'{nm}' has no single value in {scope.where}: write initial({nm}, "
                                f"\"{owner}\") or final({nm}, \"{owner}\")")
        if kind is None:
            if nm in FUNCTIONS or nm in scope.tables or nm in BOUNDARY_FUNCTIONS:
                self.fail(node, f"function '{nm}' used as a value")
            suggestion = closest(nm, list(scope.names) + ["pi"])
            hint = f"; did you mean '{suggestion}'?" if suggestion else ""
            self.fail(node, f"unknown name '{nm}'{hint}")
        if scope.boundary and kind in ("state", "control"):
            self.fail(node, f"{kind} '{nm}' has no single value in {scope.where}: write "
                            f"initial({nm}) or final({nm})")
        return Name(nm, kind)

    def call(self, node: ast.Call) -> Expr:
        if not isinstance(node.func, ast.Name):
            self.fail(node, "only calls of a function by its name are allowed")
        if node.keywords:
            self.fail(node, "keyword arguments are not allowed")
        if any(isinstance(a, ast.Starred) for a in node.args):
            self.fail(node, "starred arguments are not allowed")
        fn, nargs = node.func.id, len(node.args)
        if self.scope.phases is not None and (fn in BOUNDARY_FUNCTIONS or fn in ("t0", "tf")):
            return self.event(node, fn)
        if fn in BOUNDARY_FUNCTIONS:
            if not self.scope.boundary:
                self.fail(node, f"{fn}() is allowed only in boundary constraints and the objective's "
                                f"expr, not in {self.scope.where}")
            if nargs != 1 or not isinstance(node.args[0], ast.Name):
                self.fail(node, f"{fn}() takes one state or control name")
            arg = node.args[0].id
            kind = self.scope.names.get(arg)
            if kind not in ("state", "control"):
                cands = [n for n, k in self.scope.names.items() if k in ("state", "control")]
                suggestion = closest(arg, cands)
                hint = f"; did you mean '{suggestion}'?" if suggestion else ""
                self.fail(node, f"{fn}() of '{arg}', which is not a declared state or control{hint}")
            return Boundary(fn, arg, kind)
        if fn in self.scope.tables:
            dim = self.scope.tables[fn]
            if nargs != dim:
                self.fail(node, f"table '{fn}' is {dim}-D and takes {dim} argument{'s' * (dim > 1)}, "
                                f"not {nargs}")
            return Call(fn, tuple(self.convert(a) for a in node.args), table=True)
        if fn in FUNCTIONS:
            lo, hi = FUNCTIONS[fn]
            if nargs < lo or (hi is not None and nargs > hi):
                want = str(lo) if lo == hi else (f"{lo} or more" if hi is None else f"{lo} to {hi}")
                self.fail(node, f"{fn}() takes {want} argument{'s' * (want != '1')}, not {nargs}")
            return Call(fn, tuple(self.convert(a) for a in node.args))
        suggestion = closest(fn, list(FUNCTIONS) + list(self.scope.tables))
        hint = f"; did you mean '{suggestion}'?" if suggestion else ""
        self.fail(node, f"unknown function '{fn}'{hint}")

    def phase_of(self, node: ast.AST, arg: ast.AST, fn: str) -> str:
        """The phase a multi-phase event call names: its string literal (the only place one may be)."""
        phases = self.scope.phases
        assert phases is not None  # called for a problem of several phases only
        if not (isinstance(arg, ast.Constant) and isinstance(arg.value, str)):
            self.fail(node, f"{fn}() names its phase by a string literal, e.g. \"{next(iter(phases), 'phase')}\"")
        if arg.value not in phases:
            suggestion = closest(arg.value, list(phases))
            hint = f"; did you mean '{suggestion}'?" if suggestion else ""
            self.fail(arg, f"unknown phase '{arg.value[:64]}'{hint}")
        return arg.value

    def event(self, node: ast.Call, fn: str) -> Expr:
        """``initial(x, "phase")``, ``final(x, "phase")``, ``t0("phase")``, ``tf("phase")``."""
        if not self.scope.boundary:
            self.fail(node, f"{fn}() is allowed only in the objective's expr and links, not in {self.scope.where}")
        if fn in ("t0", "tf"):
            if len(node.args) != 1:
                self.fail(node, f"{fn}() takes one argument, the phase's name as a string")
            return EventTime(fn, self.phase_of(node, node.args[0], fn))
        if len(node.args) != 2 or not isinstance(node.args[0], ast.Name):
            self.fail(node, f"{fn}() takes a state or control name and the phase's name: {fn}(x, \"phase\")")
        phase = self.phase_of(node, node.args[1], fn)
        assert self.scope.phases is not None  # (phase_of checked it)
        arg, declared = node.args[0].id, self.scope.phases[phase]
        kind = declared.get(arg)
        if kind not in ("state", "control"):
            suggestion = closest(arg, list(declared))
            hint = f"; did you mean '{suggestion}'?" if suggestion else ""
            self.fail(node, f"{fn}() of '{arg}', which is not a state or control of phase '{phase}'{hint}")
        return Boundary(fn, arg, kind, phase)
