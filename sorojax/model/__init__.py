"""Immutable model pytrees: materials, sections, bases, joints, links, linkage, loads."""

from ._basis import (
    AbstractPolynomialBasis as AbstractPolynomialBasis,
    AbstractStrainBasis as AbstractStrainBasis,
    CustomBasis as CustomBasis,
    LegendreBasis as LegendreBasis,
    MonomialBasis as MonomialBasis,
)
from ._joint import Joint as Joint
from ._layout import Layout as Layout
from ._link import (
    AbstractLink as AbstractLink,
    Division as Division,
    RigidLink as RigidLink,
    SoftLink as SoftLink,
    translation as translation,
)
from ._linkage import Linkage as Linkage
from ._loads import PointWrench as PointWrench
from ._material import Material as Material
from ._profile import (
    AbstractProfile as AbstractProfile,
    Constant as Constant,
    Custom as Custom,
    Linear as Linear,
)
from ._section import (
    AbstractSection as AbstractSection,
    CircularSection as CircularSection,
    EllipticalSection as EllipticalSection,
    RectangularSection as RectangularSection,
)
