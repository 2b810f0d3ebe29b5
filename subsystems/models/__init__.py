"""Registry of subsystem models: the names scenes use, mapped to classes.

``model_class(name)`` finds a scene's model: a built-in one by name (``MODELS``), an FMU (``"fmu"``), a
user's Python model (``"package.module:Class"``) or one that a package registers in the entry-point
group ``zencosim.models`` (``subsystems.models.external``; docs/models.md).

A model class has ``read(table, key, problems, directory) -> spec`` (its scene parameters; paths in
them are relative to ``directory``, the scene file's), a constructor
``Model(spec, attachments)`` and the dynamics interface used by the integrators
(``initial_state``, ``outputs_at``, ``inputs``, ``outputs``, ``effects``; ``n_dof`` and
``acceleration`` for a second-order model, ``derivative`` for a first-order one). Class attributes
say how it can be coupled: ``second_order``, ``point_dimension`` (components of its coupling
signals), ``coupling_roles`` (force and/or motion side), ``provides_force`` (computes a coupling
force itself, without a coupling element) and ``starts_at_rest`` (starts in equilibrium with the
load of its coupling: needs the motion side's ``rest_state``). An external model's traits depend on its
component: its class's ``traits(spec)`` gives them (``model_traits``).
"""
from dataclasses import dataclass

from zencosim.subsystems.models.crane_arm import CraneArmModel
from zencosim.subsystems.models.external.model import FmuModel, python_model
from zencosim.subsystems.models.hydraulic_cylinder import HydraulicCylinderModel
from zencosim.subsystems.models.masses import MassesModel
from zencosim.subsystems.models.pendulum import PendulumModel
from zencosim.subsystems.models.planar_link import PlanarLinkModel

MODELS: dict[str, type] = {cls.name: cls for cls in (MassesModel, PendulumModel, CraneArmModel, HydraulicCylinderModel,
                                                     PlanarLinkModel)}


def model_class(name: str) -> type:
    """The model class a scene's ``model = name`` means; ``ModelClassError`` saying why there is none."""
    if name in MODELS:
        return MODELS[name]
    if name == FmuModel.name:
        return FmuModel
    return python_model(name)


@dataclass(frozen=True)
class ModelTraits:
    """What a model can do, as the scene checks need it."""

    second_order: bool  # the state is z = [q, q̇] and the model gives accelerations
    point_dimension: int  # components of its coupling signals
    coupling_roles: frozenset  # "force" and/or "motion" side of a force–displacement coupling
    provides_force: bool  # computes a coupling force itself, without a coupling element
    starts_at_rest: bool  # starts in equilibrium with its coupling's load (needs the motion side's rest_state)
    has_rest_state: bool  # can state its load at rest (for a force side that starts at rest)
    can_save_state: bool  # can be saved and restored (rollback of the implicit scheme)
    can_project: bool  # can take the projection step of a rigid joint (paper 003 Eq. 30)
    advances_itself: bool  # a co-simulation component: no zencosim integrator, no state derivative
    variable_step: bool = True  # can step by macro-steps of varying length (FMI canHandleVariableCommunicationStepSize)

    @property
    def default_integrator(self) -> str:
        """The integrator when the scene names none."""
        if self.advances_itself:
            return "own"
        return "symplectic_euler" if self.second_order else "rk4"


def model_traits(cls: type, spec) -> ModelTraits:
    """A model's traits: its class attributes, or its spec's for an external model (``traits(spec)``)."""
    source = cls.traits(spec) if hasattr(cls, "traits") else cls
    return ModelTraits(source.second_order, source.point_dimension, source.coupling_roles, source.provides_force,
                       source.starts_at_rest, hasattr(cls, "rest_state"), getattr(source, "can_save_state", True),
                       getattr(source, "can_project", hasattr(cls, "project")), getattr(source, "advances_itself", False),
                       getattr(source, "variable_step", True))
