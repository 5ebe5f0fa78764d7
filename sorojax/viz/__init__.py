"""Plots of linkage configurations (matplotlib, imported only when a plot is made).

``plot_configuration`` (alias ``plotq``) draws any configuration in 3D, with the
contact obstacles and optionally the contact forces;
``plot_reference`` (alias ``plotq0``) draws q = 0 with the coordinate frames;
``animate`` (the manual's ``plotqqd``) writes a video of a trajectory and
``plot_time_series`` plots its coordinates, tip position or energies against time;
``plot_cables`` draws the cable routes over a configuration;
``plot_equilibrium_path`` draws a load-response curve of a continuation path.
"""

from ._animate import (
    animate as animate,
)
from ._animate import (
    plot_time_series as plot_time_series,
)
from ._cables import (
    cable_polylines as cable_polylines,
)
from ._cables import (
    plot_cables as plot_cables,
)
from ._path import (
    plot_equilibrium_path as plot_equilibrium_path,
)
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
