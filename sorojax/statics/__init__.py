"""Static equilibrium via optimistix (Newton, load stepping, implicit adjoint)."""

from ._adequacy import (
    DiscretizationEstimate as DiscretizationEstimate,
)
from ._adequacy import (
    InsensitiveQuantityWarning as InsensitiveQuantityWarning,
)
from ._adequacy import (
    ModelChoice as ModelChoice,
)
from ._adequacy import (
    choose_model as choose_model,
)
from ._adequacy import (
    choose_model_dynamics as choose_model_dynamics,
)
from ._adequacy import (
    discretization_error as discretization_error,
)
from ._adequacy import (
    solve_statics_adequate as solve_statics_adequate,
)
from ._adequacy import (
    with_orders as with_orders,
)
from ._continuation import (
    CriticalPoint as CriticalPoint,
)
from ._continuation import (
    EquilibriumPath as EquilibriumPath,
)
from ._continuation import (
    continuation as continuation,
)
from ._solve import (
    equilibrium_residual as equilibrium_residual,
)
from ._solve import (
    solve_statics as solve_statics,
)
from ._stability import (
    UnstableEquilibriumWarning as UnstableEquilibriumWarning,
)
