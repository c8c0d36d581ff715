"""Compile pure point functions for the CPU with numba, keeping their source backend-free.

A point function may call other point functions of its module; each compiled copy gets a
globals table in which those names refer to the compiled versions, so the pure module itself
is never touched.
"""

import types

from numba import njit


def compile_module_functions(module, names, **options):
    """Return {name: compiled function} for the named functions of ``module``."""
    table = dict(vars(module))
    compiled = {}
    for name in names:
        f = getattr(module, name)
        clone = types.FunctionType(f.__code__, table, f.__name__, f.__defaults__, f.__closure__)
        compiled[name] = njit(cache=True, **options)(clone)
    table.update(compiled)
    return compiled
