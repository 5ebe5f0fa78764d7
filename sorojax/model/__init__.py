"""Immutable model pytrees: materials, sections, bases, joints, links, loads."""

from ._basis import (
    AbstractPolynomialBasis as AbstractPolynomialBasis,
)
from ._basis import (
    AbstractStrainBasis as AbstractStrainBasis,
)
from ._basis import (
    CustomBasis as CustomBasis,
)
from ._basis import (
    LegendreBasis as LegendreBasis,
)
from ._basis import (
    MonomialBasis as MonomialBasis,
)
from ._joint import Joint as Joint
from ._layout import Layout as Layout
from ._link import (
    AbstractLink as AbstractLink,
)
from ._link import (
    Division as Division,
)
from ._link import (
    RigidLink as RigidLink,
)
from ._link import (
    SoftLink as SoftLink,
)
from ._link import (
    translation as translation,
)
from ._linkage import Linkage as Linkage
from ._loads import PointWrench as PointWrench
from ._material import Material as Material
from ._profile import (
    AbstractProfile as AbstractProfile,
)
from ._profile import (
    Constant as Constant,
)
from ._profile import (
    Custom as Custom,
)
from ._profile import (
    Linear as Linear,
)
from ._section import (
    AbstractSection as AbstractSection,
)
from ._section import (
    CircularSection as CircularSection,
)
from ._section import (
    EllipticalSection as EllipticalSection,
)
from ._section import (
    RectangularSection as RectangularSection,
)
