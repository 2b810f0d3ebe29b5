"""Registry of subsystem models: the names scenes use, mapped to classes.

A model class has ``read(table, key, problems) -> spec`` (its scene parameters), a constructor
``Model(spec, attachments)`` and the dynamics interface used by the integrators
(``n_dof``, ``initial_state``, ``acceleration``, ``outputs_at``, ``inputs``, ``outputs``, ``effects``).
"""
from subsystems.masses import MassesModel

MODELS: dict[str, type] = {cls.name: cls for cls in (MassesModel,)}
