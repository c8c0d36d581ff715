"""Safe evaluation of small math expressions of the reference coordinates x, y (and z).

Used for initial velocity fields in case files, e.g. ``"10*sin(pi*x/0.0324)"``. The string is
parsed with :mod:`ast` and walked node by node: only numbers, the coordinate names, pi and e, the
arithmetic operators and a fixed set of numpy functions are accepted. Nothing is ever passed
to Python's ``eval``.
"""

from __future__ import annotations

import ast
import operator

import numpy as np

from .errors import InputError

# name -> (function, number of arguments). Each is called with exactly that many
# positional arguments, so no numpy keyword or extra positional argument (``out``, which
# would write into the caller's arrays) can be reached.
_FUNCTIONS = {
    "sin": (np.sin, 1), "cos": (np.cos, 1), "tan": (np.tan, 1), "exp": (np.exp, 1),
    "log": (np.log, 1), "sqrt": (np.sqrt, 1), "abs": (np.abs, 1), "tanh": (np.tanh, 1),
    "sinh": (np.sinh, 1), "cosh": (np.cosh, 1), "arcsin": (np.arcsin, 1),
    "arccos": (np.arccos, 1), "arctan": (np.arctan, 1), "arctan2": (np.arctan2, 2),
    "heaviside": (lambda a: np.heaviside(a, 0.5), 1), "minimum": (np.minimum, 2),
    "maximum": (np.maximum, 2),
}
MAX_LENGTH = 1000       # characters of one expression
MAX_DEPTH = 50          # nesting of operations and calls
_CONSTANTS = {"pi": np.pi, "e": np.e}
_BINARY = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul,
           ast.Div: operator.truediv, ast.Pow: operator.pow}
_UNARY = {ast.USub: operator.neg, ast.UAdd: operator.pos}
_VARIABLES = ("x", "y")


def compile_expression(text: str, key: str, variables=_VARIABLES):
    """Check ``text`` and return a function f(*coordinates) -> array of the ``variables``
    (x, y; or x, y, z in 3D). Raises InputError naming ``key``."""
    if len(text) > MAX_LENGTH:
        raise InputError(f"{key}: expression of {len(text)} characters; at most {MAX_LENGTH} "
                         "are accepted")
    try:
        tree = ast.parse(text.strip(), mode="eval")
    except (SyntaxError, ValueError, RecursionError, MemoryError):
        raise InputError(f"{key}: cannot parse expression {_short(text)}") from None
    depth = _depth(tree.body)
    if depth > MAX_DEPTH:
        raise InputError(f"{key}: expression nested {depth} deep; at most {MAX_DEPTH} levels "
                         "are accepted")
    _check(tree.body, key, text, tuple(variables))

    def evaluate(*coordinates):
        try:
            with np.errstate(all="ignore"):
                value = _eval(tree.body, dict(zip(variables, coordinates)))
            if np.iscomplexobj(value):
                raise ValueError("complex values")
            return np.broadcast_to(np.asarray(value, dtype=float),
                                   np.shape(coordinates[0])).copy()
        except (TypeError, ValueError, ArithmeticError) as exc:
            raise InputError(f"{key}: cannot evaluate {_short(text)} ({exc})") from None

    return evaluate


def _check(node, key, text, variables):
    allowed = ", ".join(sorted(_FUNCTIONS))
    names = ", ".join(variables)
    if isinstance(node, ast.Constant):
        if not isinstance(node.value, (int, float)) or isinstance(node.value, bool):
            raise InputError(f"{key}: only numbers are allowed as constants in {_short(text)}")
    elif isinstance(node, ast.Name):
        if node.id not in variables and node.id not in _CONSTANTS:
            raise InputError(f"{key}: unknown name {node.id!r} in {_short(text)} "
                             f"(expected {names}, pi, e)")
    elif isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
        _check(node.left, key, text, variables)
        _check(node.right, key, text, variables)
    elif isinstance(node, ast.UnaryOp) and type(node.op) in _UNARY:
        _check(node.operand, key, text, variables)
    elif isinstance(node, ast.Call) and isinstance(node.func, ast.Name) \
            and node.func.id in _FUNCTIONS and not node.keywords:
        arity = _FUNCTIONS[node.func.id][1]
        if len(node.args) != arity or any(isinstance(a, ast.Starred) for a in node.args):
            raise InputError(f"{key}: {node.func.id}() takes {arity} argument"
                             f"{'s' if arity > 1 else ''}, got {len(node.args)} in {_short(text)}")
        for arg in node.args:
            _check(arg, key, text, variables)
    else:
        raise InputError(f"{key}: unsupported syntax in {_short(text)} (allowed: numbers, {names}, "
                         f"pi, e, + - * / **, and the functions {allowed})")


def _eval(node, variables):
    if isinstance(node, ast.Constant):
        # numpy semantics from the first number on: (-8) ** (1/3) is NaN (refused as a
        # non-finite value), not the complex number of Python floats, whose real part
        # would silently become the velocity
        return np.float64(node.value)
    if isinstance(node, ast.Name):
        return variables[node.id] if node.id in variables else _CONSTANTS[node.id]
    if isinstance(node, ast.BinOp):
        return _BINARY[type(node.op)](_eval(node.left, variables), _eval(node.right, variables))
    if isinstance(node, ast.UnaryOp):
        return _UNARY[type(node.op)](_eval(node.operand, variables))
    function, arity = _FUNCTIONS[node.func.id]
    return function(*[_eval(a, variables) for a in node.args[:arity]])


def _depth(root) -> int:
    """Nesting depth of an expression tree, walked without recursion (a chain of thousands
    of unary minus signs must not exhaust Python's stack)."""
    deepest, stack = 0, [(root, 1)]
    while stack:
        node, level = stack.pop()
        deepest = max(deepest, level)
        if deepest > MAX_DEPTH:
            break
        stack.extend((child, level + 1) for child in ast.iter_child_nodes(node))
    return deepest


def _short(text: str) -> str:
    """The expression for a one-line message: repr (no raw control characters), clipped."""
    shown = repr(text)
    return shown if len(shown) <= 80 else shown[:77] + "..."
