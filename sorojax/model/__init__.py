"""Immutable model pytrees: materials, sections, bases, joints, links, loads."""

from ._actuation import AbstractCablePath as AbstractCablePath
from ._actuation import Cable as Cable
from ._actuation import CableAnchor as CableAnchor
from ._actuation import CableSpan as CableSpan
from ._actuation import ConstantPath as ConstantPath
from ._actuation import CustomPath as CustomPath
from ._actuation import HelicalPath as HelicalPath
from ._actuation import JointActuator as JointActuator
from ._actuation import ObliquePath as ObliquePath
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
from ._basis import (
    PaddedBasis as PaddedBasis,
)
from ._closure import ClosedLoopJoint as ClosedLoopJoint
from ._contact import AbstractContactShape as AbstractContactShape
from ._contact import AbstractObstacle as AbstractObstacle
from ._contact import Box as Box
from ._contact import Capsule as Capsule
from ._contact import Contact as Contact
from ._contact import ContactBox as ContactBox
from ._contact import ContactCapsule as ContactCapsule
from ._contact import ContactLaw as ContactLaw
from ._contact import ContactSphere as ContactSphere
from ._contact import Plane as Plane
from ._contact import Sphere as Sphere
from ._hook import Hook as Hook
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
from ._section import AnnularSection as AnnularSection
from ._section import (
    CircularSection as CircularSection,
)
from ._section import (
    EllipticalSection as EllipticalSection,
)
from ._section import (
    RectangularSection as RectangularSection,
)
from ._section import SectionProperties as SectionProperties
from ._section import rectangle_torsion_constant as rectangle_torsion_constant
from ._section import sorosim_mechanics as sorosim_mechanics
from ._size_class import active_coordinates as active_coordinates
from ._size_class import size_class as size_class
