"""Static equilibrium via optimistix (Newton, load stepping, implicit adjoint)."""

from ._solve import (
    equilibrium_residual as equilibrium_residual,
)
from ._solve import (
    solve_statics as solve_statics,
)
