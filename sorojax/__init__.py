"""sorojax: differentiable simulation of hybrid soft/rigid robots (GVS approach) in JAX.

Conventions: SI units; 6-vectors angular first ``(wx, wy, wz, vx, vy, vz)``; wrenches
``(moment, force)``; rod axis local x; links numbered from 1 (0 = ground).

Most names below are imported on first use (PEP 562): ``import sorojax`` costs
the JAX import and the model and kinematics modules, so a statics-only script or
``sorojax demo`` does not wait for diffrax, optimistix and the rest (~0.4 s on a
2-core CPU).
"""

import importlib
from typing import TYPE_CHECKING

# ``kinematics`` is a function and a submodule: bound here, after the submodule's
# import (which sets the package attribute to the module), the function wins.
from .kinematics import kinematics as kinematics

__version__ = "0.1.0"

# public name -> the module it lives in (relative to this package)
_LAZY = {
    "enable_compilation_cache": "._cache",
    "compiler_options": "._jit",
    "compile_mode": "._jit",
    "jit": "._jit",
    "prepare": "._jit",
    "set_runtime_flags": "._jit",
    "RESULTS": "._results",
    "StaticsSolution": "._results",
    "sweep": "._sweep",
    "initialize_processes": "._sweep",
    "process_sum": "._sweep",
    "Environment": ".control",
    "EnvState": ".control",
    "rollout": ".control",
    "AnnularSection": ".model",
    "Box": ".model",
    "Capsule": ".model",
    "Contact": ".model",
    "ContactBox": ".model",
    "ContactCapsule": ".model",
    "ContactLaw": ".model",
    "ContactSphere": ".model",
    "Plane": ".model",
    "Sphere": ".model",
    "ContactState": ".dynamics",
    "contact_energy": ".dynamics",
    "contact_state": ".dynamics",
    "actuation_matrix": ".dynamics",
    "cable_lengths": ".dynamics",
    "closure_errors": ".dynamics",
    "constraint_jacobian": ".dynamics",
    "coriolis_force": ".dynamics",
    "coriolis_matrix": ".dynamics",
    "damping_matrix": ".dynamics",
    "elastic_energy": ".dynamics",
    "equations_of_motion": ".dynamics",
    "forward_dynamics": ".dynamics",
    "generalized_external_force": ".dynamics",
    "gravitational_energy": ".dynamics",
    "kinetic_energy": ".dynamics",
    "mass_matrix": ".dynamics",
    "stiffness_matrix": ".dynamics",
    "total_energy": ".dynamics",
    "SOLVERS": ".integrate",
    "Trajectory": ".integrate",
    "simulate": ".integrate",
    "load_trajectory": ".io",
    "save_trajectory": ".io",
    "SceneError": ".io",
    "load_linkage": ".io",
    "load_scene": ".io",
    "save_linkage": ".io",
    "Kinematics": ".kinematics",
    "forward_kinematics": ".kinematics",
    "jacobians": ".kinematics",
    "jacobians_time_derivative": ".kinematics",
    "screw_strains": ".kinematics",
    "screw_velocities": ".kinematics",
    "strain_coordinates": ".kinematics",
    "tip_pose": ".kinematics",
    "Cable": ".model",
    "CableAnchor": ".model",
    "CableSpan": ".model",
    "CircularSection": ".model",
    "ClosedLoopJoint": ".model",
    "ConstantPath": ".model",
    "CustomBasis": ".model",
    "CustomPath": ".model",
    "Division": ".model",
    "EllipticalSection": ".model",
    "HelicalPath": ".model",
    "Joint": ".model",
    "JointActuator": ".model",
    "LegendreBasis": ".model",
    "Linkage": ".model",
    "Material": ".model",
    "MonomialBasis": ".model",
    "PaddedBasis": ".model",
    "ObliquePath": ".model",
    "PointWrench": ".model",
    "RectangularSection": ".model",
    "RigidLink": ".model",
    "SectionProperties": ".model",
    "SoftLink": ".model",
    "rectangle_torsion_constant": ".model",
    "active_coordinates": ".model",
    "size_class": ".model",
    "sorosim_mechanics": ".model",
    "translation": ".model",
    "precompute": ".model._precompute",
    "RecompilationWarning": "._recompile",
    "CriticalPoint": ".statics",
    "EquilibriumPath": ".statics",
    "InsensitiveQuantityWarning": ".statics",
    "ModelChoice": ".statics",
    "UnstableEquilibriumWarning": ".statics",
    "choose_model": ".statics",
    "choose_model_dynamics": ".statics",
    "continuation": ".statics",
    "discretization_error": ".statics",
    "solve_statics": ".statics",
    "solve_statics_adequate": ".statics",
    "with_orders": ".statics",
}
_SUBMODULES = frozenset(
    {
        "contrib",
        "control",
        "dynamics",
        "integrate",
        "io",
        "kinematics",
        "lie",
        "model",
        "scenes",
        "statics",
        "viz",
    }
)
__all__ = sorted({*_LAZY, "kinematics"})


def __getattr__(name: str):
    """Import a public name (or a submodule) on first access."""
    if name in _LAZY:
        value = getattr(importlib.import_module(_LAZY[name], __name__), name)
        globals()[name] = value  # later accesses skip this function
        return value
    if name in _SUBMODULES:
        return importlib.import_module("." + name, __name__)
    raise AttributeError(f"module 'sorojax' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_LAZY) | _SUBMODULES)


if TYPE_CHECKING:  # static analysers see the names as plain imports
    from ._cache import enable_compilation_cache as enable_compilation_cache
    from ._jit import compile_mode as compile_mode
    from ._jit import compiler_options as compiler_options
    from ._jit import jit as jit
    from ._jit import prepare as prepare
    from ._jit import set_runtime_flags as set_runtime_flags
    from ._recompile import RecompilationWarning as RecompilationWarning
    from ._results import RESULTS as RESULTS
    from ._results import StaticsSolution as StaticsSolution
    from ._sweep import initialize_processes as initialize_processes
    from ._sweep import process_sum as process_sum
    from ._sweep import sweep as sweep
    from .control import Environment as Environment
    from .control import EnvState as EnvState
    from .control import rollout as rollout
    from .dynamics import ContactState as ContactState
    from .dynamics import actuation_matrix as actuation_matrix
    from .dynamics import cable_lengths as cable_lengths
    from .dynamics import closure_errors as closure_errors
    from .dynamics import constraint_jacobian as constraint_jacobian
    from .dynamics import contact_energy as contact_energy
    from .dynamics import contact_state as contact_state
    from .dynamics import coriolis_force as coriolis_force
    from .dynamics import coriolis_matrix as coriolis_matrix
    from .dynamics import damping_matrix as damping_matrix
    from .dynamics import elastic_energy as elastic_energy
    from .dynamics import equations_of_motion as equations_of_motion
    from .dynamics import forward_dynamics as forward_dynamics
    from .dynamics import generalized_external_force as generalized_external_force
    from .dynamics import gravitational_energy as gravitational_energy
    from .dynamics import kinetic_energy as kinetic_energy
    from .dynamics import mass_matrix as mass_matrix
    from .dynamics import stiffness_matrix as stiffness_matrix
    from .dynamics import total_energy as total_energy
    from .integrate import SOLVERS as SOLVERS
    from .integrate import Trajectory as Trajectory
    from .integrate import simulate as simulate
    from .io import SceneError as SceneError
    from .io import load_linkage as load_linkage
    from .io import load_scene as load_scene
    from .io import load_trajectory as load_trajectory
    from .io import save_linkage as save_linkage
    from .io import save_trajectory as save_trajectory
    from .kinematics import Kinematics as Kinematics
    from .kinematics import forward_kinematics as forward_kinematics
    from .kinematics import jacobians as jacobians
    from .kinematics import jacobians_time_derivative as jacobians_time_derivative
    from .kinematics import kinematics as kinematics
    from .kinematics import screw_strains as screw_strains
    from .kinematics import screw_velocities as screw_velocities
    from .kinematics import strain_coordinates as strain_coordinates
    from .kinematics import tip_pose as tip_pose
    from .model import AnnularSection as AnnularSection
    from .model import Box as Box
    from .model import Cable as Cable
    from .model import CableAnchor as CableAnchor
    from .model import CableSpan as CableSpan
    from .model import Capsule as Capsule
    from .model import CircularSection as CircularSection
    from .model import ClosedLoopJoint as ClosedLoopJoint
    from .model import ConstantPath as ConstantPath
    from .model import Contact as Contact
    from .model import ContactBox as ContactBox
    from .model import ContactCapsule as ContactCapsule
    from .model import ContactLaw as ContactLaw
    from .model import ContactSphere as ContactSphere
    from .model import CustomBasis as CustomBasis
    from .model import CustomPath as CustomPath
    from .model import Division as Division
    from .model import EllipticalSection as EllipticalSection
    from .model import HelicalPath as HelicalPath
    from .model import Joint as Joint
    from .model import JointActuator as JointActuator
    from .model import LegendreBasis as LegendreBasis
    from .model import Linkage as Linkage
    from .model import Material as Material
    from .model import MonomialBasis as MonomialBasis
    from .model import ObliquePath as ObliquePath
    from .model import PaddedBasis as PaddedBasis
    from .model import Plane as Plane
    from .model import PointWrench as PointWrench
    from .model import RectangularSection as RectangularSection
    from .model import RigidLink as RigidLink
    from .model import SectionProperties as SectionProperties
    from .model import SoftLink as SoftLink
    from .model import Sphere as Sphere
    from .model import active_coordinates as active_coordinates
    from .model import rectangle_torsion_constant as rectangle_torsion_constant
    from .model import size_class as size_class
    from .model import sorosim_mechanics as sorosim_mechanics
    from .model import translation as translation
    from .model._precompute import precompute as precompute
    from .statics import CriticalPoint as CriticalPoint
    from .statics import EquilibriumPath as EquilibriumPath
    from .statics import InsensitiveQuantityWarning as InsensitiveQuantityWarning
    from .statics import ModelChoice as ModelChoice
    from .statics import UnstableEquilibriumWarning as UnstableEquilibriumWarning
    from .statics import choose_model as choose_model
    from .statics import choose_model_dynamics as choose_model_dynamics
    from .statics import continuation as continuation
    from .statics import discretization_error as discretization_error
    from .statics import solve_statics as solve_statics
    from .statics import solve_statics_adequate as solve_statics_adequate
    from .statics import with_orders as with_orders
