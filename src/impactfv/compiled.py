"""The CPU backend: numba compilation of backend-free point functions, and small local arrays.

Point functions (material laws, Riemann states, limiters) are plain Python on scalars and
small arrays; they never allocate and read the dimension from the shapes of their arrays.
Kernels, the loops around them, copy a node's or an edge's data into local arrays from
:func:`local_vector` / :func:`local_matrix` and hand those to the point functions: they live
on the stack, so LLVM keeps them in registers, and their shape is a compile-time constant, so
the loops inside the point functions unroll (a heap array per block cost 25% in the flux
loop; passing views of the global arrays, whose shapes are only known at run time, cost 40%
in the stress loop; local copies cost 8-12% against hand-written 2D scalar code). A GPU
backend would hand the same point functions ``cuda.local.array`` instead.

Kernels are dimension-generic: they take ``dim``, a tuple of ``d`` zeros (see
:func:`dim_tag`), and use ``len(dim)`` as the space dimension. The length of a tuple is part
of its numba type, so each dimension gets its own compiled (and cached) specialisation in
which ``d`` is a compile-time constant and the loops over components unroll; with ``d`` read
from an array shape at run time the flux loop ran 2.4 times slower.
"""

import contextlib
import os
import types

import numba.core.config
from numba import carray, njit
from numba import types as nbtypes
from numba.core import cgutils
from numba.extending import intrinsic

#: largest space dimension; local arrays are sized for it
MAX_DIM = 3

#: LLVM flags of the scheme's kernels: only contraction of a * b + c into one fused
#: multiply-add (rounded once instead of twice) where the CPU has FMA; no reassociation,
#: no assumptions about NaN or infinity, so the sums keep their order and a bad state is
#: still seen. It makes the gradient and flux loops faster (docs/performance.md); results
#: change at round-off only (a GPU contracts the same way by default). numba's cache does
#: not see a change of these flags: clear the __pycache__ folders after changing them.
KERNEL_FASTMATH = {"contract"}


@contextlib.contextmanager
def superword_vectorization(enabled: bool):
    """Kernels compiled inside this block use LLVM's superword-level-parallelism (SLP)
    vectorizer if ``enabled``; numba leaves it off by default (numba.core.config
    SLP_VECTORIZE, read when a kernel is compiled, i.e. at its first call). The 3D
    gradient loop over nine fields runs 2.3 times faster with it; the 2D one (five fields)
    runs 15% slower (docs/performance.md), so the stepper enables it for 3D runs only.
    NUMBA_SLP_VECTORIZE set in the environment takes precedence. A kernel already compiled
    (or loaded from numba's cache, which does not record the flag) keeps its code: results
    are the same either way."""
    if "NUMBA_SLP_VECTORIZE" in os.environ:
        yield
        return
    previous = numba.core.config.SLP_VECTORIZE
    numba.core.config.SLP_VECTORIZE = int(enabled)
    try:
        yield
    finally:
        numba.core.config.SLP_VECTORIZE = previous


def dim_tag(dim: int) -> tuple:
    """The ``dim`` argument of the kernels: a tuple of ``dim`` zeros."""
    return (0,) * int(dim)


_compiled = {}


def variant(enabled: bool) -> tuple:
    """A compile-time option of compiled code: ``if option:`` is decided when numba
    specialises the function on the option's type (an empty tuple is false, a one-element
    tuple true), so that each option set compiles its own code, without the branch, as
    dim_tag does for the dimension."""
    return (0,) if enabled else ()


def point(f, inline: bool = True):
    """The numba-compiled copy of point function ``f`` (compiled once, cached on disk).

    A point function may call other point functions (of its own module or another impactfv
    module); its copy gets a globals table in which those names refer to their compiled
    copies, so the pure modules themselves are never touched.

    ``inline``: numba inlines the copy into its callers (the default), where the loops
    over components unroll and the local arrays stay in registers; numba then types and
    lowers its body again at every call site. With False it is a function of its own,
    compiled once and called: for kernels' cold paths (output fields, on-demand monitors),
    where an inlined material law costs seconds of compilation and a call costs nothing
    that matters. On a hot path a call costs about 50 ns (the arrays are passed field by
    field): the node loops ran twice as slow (docs/performance.md, "Compilation").
    """
    compile_copy = njit(cache=True, inline="always" if inline else "never")
    return _compiled_copy(f, (f, inline), compile_copy, point)


def device(f):
    """The CUDA device-function copy of point function ``f`` (compiled once, when the
    first CUDA kernels are made), its calls to other point functions made to their device
    copies as in :func:`point`. numba-cuda is imported here, only when asked for."""
    from numba import cuda as _cuda

    return _compiled_copy(f, (f, "cuda"), _cuda.jit(device=True), device)


def _compiled_copy(f, key, compile_copy, copy_of):
    """``compile_copy`` of a clone of ``f`` whose globals name ``copy_of`` each impactfv
    function it calls (once per ``key``)."""
    if key in _compiled:
        return _compiled[key]
    table = dict(f.__globals__)
    clone = types.FunctionType(f.__code__, table, f.__name__, f.__defaults__, f.__closure__)
    clone.__module__ = f.__module__
    clone.__qualname__ = f.__qualname__
    compiled = _compiled[key] = compile_copy(clone)
    for name in f.__code__.co_names:
        g = table.get(name)
        if isinstance(g, types.FunctionType) and g.__module__.startswith("impactfv."):
            table[name] = copy_of(g)
    return compiled


@intrinsic
def _stack_buffer(typingctx, size):
    """A float64 buffer of ``size`` (a literal int) entries on the stack of the caller."""
    if not isinstance(size, nbtypes.IntegerLiteral):
        return None
    count = size.literal_value

    def codegen(context, builder, signature, args):
        return cgutils.alloca_once(builder, context.get_value_type(nbtypes.float64),
                                   size=count)
    return nbtypes.CPointer(nbtypes.float64)(size), codegen


@njit(inline="always")
def local_vector(d):
    """A scratch vector of length d (d <= MAX_DIM) on the stack."""
    return carray(_stack_buffer(3), d)


@njit(inline="always")
def local_matrix(d):
    """A scratch d x d matrix (d <= MAX_DIM) on the stack."""
    return carray(_stack_buffer(9), (d, d))


@njit(inline="always")
def local_components(m):
    """A scratch vector of m <= 16 entries on the stack (one per reconstructed field)."""
    return carray(_stack_buffer(16), m)


@njit(inline="always")
def local_rows(k, d):
    """k scratch vectors of length d (k d <= 48) on the stack, as the rows of one array."""
    return carray(_stack_buffer(48), (k, d))


@njit(inline="always")
def local_scratch(k):
    """A flat scratch vector of k <= 48 entries on the stack."""
    return carray(_stack_buffer(48), k)


@njit(inline="always")
def load_vector(u, a, out):
    """out = u[a] (out a local vector)."""
    for i in range(out.shape[0]):
        out[i] = u[a, i]


@njit(inline="always")
def load_matrix(F, a, out):
    """out = F[a] (out a local matrix)."""
    for i in range(out.shape[0]):
        for J in range(out.shape[1]):
            out[i, J] = F[a, i, J]


@njit(inline="always")
def store_matrix(out, F, a):
    """F[a] = out (out a local matrix)."""
    for i in range(out.shape[0]):
        for J in range(out.shape[1]):
            F[a, i, J] = out[i, J]
