"""The ground floor: the physics as point functions of one node, face or contact pair
(materials, tensors, Riemann states, limiters, the Runge-Kutta stage, contact laws).

Plain Python on scalars and small arrays, free of numba: impactfv.compiled compiles them for
a CPU loop (``point``) or a CUDA kernel (``device``). They import nothing of impactfv but
each other.
"""
