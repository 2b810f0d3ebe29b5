"""zencosim: distributed, real-time co-simulation of mechanical and multiphysics systems over Eclipse Zenoh.

The Python API (docs/api.md)::

    import zencosim
    result = zencosim.run(zencosim.load_scene("two_mass_damped", {"manager.macro_step": 0.002}))
    result.signal("x2").values

The API's names are imported from ``zencosim.api`` when first used, so that a subsystem or recorder
process, which imports only what it runs, does not pay for the rest.
"""
from importlib.metadata import version

__version__ = version("zencosim")

_API = ("BUSES", "MissingExtra", "OutputFileError", "ProtocolError", "Recording", "RecordingError", "Result",
        "Scene", "SceneError", "SecurityError", "Signal", "SubsystemFailure", "Table", "bundled_scenes",
        "load_recording", "load_scene", "run")
__all__ = ["__version__", *_API]


def __getattr__(name: str):
    if name in _API:
        from zencosim import api
        return getattr(api, name)
    raise AttributeError(f"module 'zencosim' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(__all__)
