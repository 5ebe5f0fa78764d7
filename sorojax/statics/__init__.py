"""Static equilibrium via optimistix (Newton by default, load stepping, implicit adjoint)."""

from ._solve import (
    equilibrium_residual as equilibrium_residual,
    solve_statics as solve_statics,
)
