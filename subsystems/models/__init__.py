"""Registry of subsystem models: the names scenes use, mapped to classes.

A model class has ``read(table, key, problems) -> spec`` (its scene parameters), a constructor
``Model(spec, attachments)`` and the dynamics interface used by the integrators
(``initial_state``, ``outputs_at``, ``inputs``, ``outputs``, ``effects``; ``n_dof`` and
``acceleration`` for a second-order model, ``derivative`` for a first-order one). Class attributes
say how it can be coupled: ``second_order``, ``point_dimension`` (components of its coupling
signals), ``coupling_roles`` (force and/or motion side), ``provides_force`` (computes a coupling
force itself, without a coupling element) and ``starts_at_rest`` (starts in equilibrium with the
load of its coupling: needs the motion side's ``rest_state``).
"""
from zencosim.subsystems.models.crane_arm import CraneArmModel
from zencosim.subsystems.models.hydraulic_cylinder import HydraulicCylinderModel
from zencosim.subsystems.models.masses import MassesModel
from zencosim.subsystems.models.pendulum import PendulumModel
from zencosim.subsystems.models.planar_link import PlanarLinkModel

MODELS: dict[str, type] = {cls.name: cls for cls in (MassesModel, PendulumModel, CraneArmModel, HydraulicCylinderModel,
                                                     PlanarLinkModel)}
