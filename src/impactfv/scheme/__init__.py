"""The upwind vertex-centred finite volume scheme: point functions of the fluxes, limiters and
Runge-Kutta stage, the assembled arrays, compiled kernels and the FV stepper."""
