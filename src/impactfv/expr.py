"""Safe evaluation of small math expressions of the reference coordinates x and y.

Used for initial velocity fields in case files, e.g. ``"10*sin(pi*x/0.0324)"``. The string is
parsed with :mod:`ast` and walked node by node: only numbers, the names x, y, pi and e, the
arithmetic operators and a fixed set of numpy functions are accepted. Nothing is ever passed
to Python's ``eval``.
"""

from __future__ import annotations

import ast
import operator

import numpy as np

from .errors import InputError

_FUNCTIONS = {
    "sin": np.sin, "cos": np.cos, "tan": np.tan, "exp": np.exp, "log": np.log,
    "sqrt": np.sqrt, "abs": np.abs, "tanh": np.tanh, "sinh": np.sinh, "cosh": np.cosh,
    "arcsin": np.arcsin, "arccos": np.arccos, "arctan": np.arctan, "arctan2": np.arctan2,
    "heaviside": lambda a: np.heaviside(a, 0.5), "minimum": np.minimum, "maximum": np.maximum,
}
_CONSTANTS = {"pi": np.pi, "e": np.e}
_BINARY = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul,
           ast.Div: operator.truediv, ast.Pow: operator.pow}
_UNARY = {ast.USub: operator.neg, ast.UAdd: operator.pos}
_VARIABLES = ("x", "y")


def compile_expression(text: str, key: str):
    """Check ``text`` and return a function f(x, y) -> array. Raises InputError naming ``key``."""
    try:
        tree = ast.parse(text.strip(), mode="eval")
    except (SyntaxError, ValueError, RecursionError, MemoryError):
        raise InputError(f"{key}: cannot parse expression {text!r}") from None
    _check(tree.body, key, text)

    def evaluate(x, y):
        try:
            with np.errstate(all="ignore"):
                value = _eval(tree.body, {"x": x, "y": y})
            return np.broadcast_to(np.asarray(value, dtype=float), np.shape(x)).copy()
        except (TypeError, ValueError, ArithmeticError) as exc:
            raise InputError(f"{key}: cannot evaluate {text!r} ({exc})") from None

    return evaluate


def _check(node, key, text):
    allowed = ", ".join(sorted(_FUNCTIONS))
    if isinstance(node, ast.Constant):
        if not isinstance(node.value, (int, float)) or isinstance(node.value, bool):
            raise InputError(f"{key}: only numbers are allowed as constants in {text!r}")
    elif isinstance(node, ast.Name):
        if node.id not in _VARIABLES and node.id not in _CONSTANTS:
            raise InputError(f"{key}: unknown name {node.id!r} in {text!r} "
                             "(expected x, y, pi, e)")
    elif isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
        _check(node.left, key, text)
        _check(node.right, key, text)
    elif isinstance(node, ast.UnaryOp) and type(node.op) in _UNARY:
        _check(node.operand, key, text)
    elif isinstance(node, ast.Call) and isinstance(node.func, ast.Name) \
            and node.func.id in _FUNCTIONS and not node.keywords:
        for arg in node.args:
            _check(arg, key, text)
    else:
        raise InputError(f"{key}: unsupported syntax in {text!r} (allowed: numbers, x, y, pi, "
                         f"e, + - * / **, and the functions {allowed})")


def _eval(node, variables):
    if isinstance(node, ast.Constant):
        return float(node.value)
    if isinstance(node, ast.Name):
        return variables[node.id] if node.id in variables else _CONSTANTS[node.id]
    if isinstance(node, ast.BinOp):
        return _BINARY[type(node.op)](_eval(node.left, variables), _eval(node.right, variables))
    if isinstance(node, ast.UnaryOp):
        return _UNARY[type(node.op)](_eval(node.operand, variables))
    return _FUNCTIONS[node.func.id](*[_eval(a, variables) for a in node.args])
