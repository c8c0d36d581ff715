"""The upwind vertex-centred scheme: Riemann point functions and compiled kernels."""
