"""Plots of linkage configurations (matplotlib, imported only when a plot is made).

``plot_configuration`` (alias ``plotq``) draws any configuration in 3D;
``plot_reference`` (alias ``plotq0``) draws q = 0 with the coordinate frames.
"""

from ._plot import (
    plot_configuration as plot_configuration,
)
from ._plot import (
    plot_reference as plot_reference,
)
from ._plot import (
    plotq as plotq,
)
from ._plot import (
    plotq0 as plotq0,
)
