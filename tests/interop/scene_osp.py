"""A zencosim scene of FMUs written as an OSP system structure, for libcosim to run the same system.

:func:`write_osp` reads a TOML scene (``zencosim examples`` writes them beside their FMUs) and writes the
``OspSystemStructure.xml`` of the same system: each FMU subsystem a ``Simulator`` (its ``start`` values as
``InitialValues``, its micro-step as ``stepSize``), each ``force_displacement`` coupling three
``VariableConnection`` elements, copied unchanged by libcosim: the force side's force output to the motion
side's force input and the motion side's velocity back (both marked ``powerBond="<coupling>"``, with the
``causality`` attributes libcosim asks of a power bond), and the motion side's position to the force
side's position input. Only what libcosim can run the same way is accepted: FMI 2.0 Co-Simulation FMUs
stepped at the macro step (no communication ratios), zero-order hold, the explicit scheme, no energy
correction; anything else raises ValueError naming it.
"""
from __future__ import annotations

import os
import tomllib
from pathlib import Path
from xml.sax.saxutils import quoteattr

OSP_NAMESPACE = "http://opensimulationplatform.com/MSMI/OSPSystemStructure"


def _refuse(scene: Path, what: str) -> ValueError:
    return ValueError(f"{scene}: {what}; libcosim would not run the same system")


def _point(scene: Path, document: dict, end: str) -> tuple[str, dict]:
    subsystem, _, point = end.partition(".")
    try:
        return subsystem, document["subsystems"][subsystem]["points"][point]
    except KeyError:
        raise _refuse(scene, f"no point {end!r}") from None


def write_osp(scene: Path, out: Path) -> Path:
    """Write the OSP system structure of the scene file ``scene`` to ``out`` (FMU paths relative to
    ``out``'s directory); return ``out``."""
    scene, out = Path(scene), Path(out)
    document = tomllib.loads(scene.read_text())
    manager = document.get("manager", {})
    base = float(manager["macro_step"])
    if manager.get("scheme", "explicit") != "explicit":
        raise _refuse(scene, f"scheme {manager['scheme']!r}")
    if manager.get("extrapolation", 0) != 0:
        raise _refuse(scene, f"extrapolation {manager['extrapolation']} (libcosim holds inputs: order 0)")
    if manager.get("correction", {}).get("enabled", False) or manager.get("compensation", "none") != "none":
        raise _refuse(scene, "energy correction or compensation")
    simulators = []
    for name, subsystem in document["subsystems"].items():
        if subsystem.get("model") != "fmu" or subsystem.get("interface", "co-simulation") != "co-simulation":
            raise _refuse(scene, f"subsystems.{name} is not an FMU run for Co-Simulation")
        if subsystem.get("comm_ratio", 1) != 1 or subsystem.get("extrapolation", 0) != 0:
            raise _refuse(scene, f"subsystems.{name} has a communication ratio or its own extrapolation")
        if float(subsystem["micro_step"]) != base:
            raise _refuse(scene, f"subsystems.{name}.micro_step differs from the macro step")
        fmu = (scene.parent / subsystem["fmu"]).resolve()
        source = Path(os.path.relpath(fmu, out.parent.resolve())).as_posix()
        values = "".join(f"\n        <InitialValue variable={quoteattr(variable)}><Real value=\"{float(value)!r}\"/>"
                         "</InitialValue>" for variable, value in subsystem.get("start", {}).items())
        simulators.append(f"\n    <Simulator name={quoteattr(name)} source={quoteattr(source)} "
                          f"stepSize=\"{float(subsystem['micro_step'])!r}\">"
                          f"\n      <InitialValues>{values}\n      </InitialValues>\n    </Simulator>")
    connections = []
    for name, coupling in document.get("couplings", {}).items():
        if coupling.get("type") != "force_displacement" or coupling.get("effects"):
            raise _refuse(scene, f"couplings.{name} is not a force_displacement coupling between FMUs")
        force_side, force_point = _point(scene, document, coupling["force_side"])
        motion_side, motion_point = _point(scene, document, coupling["motion_side"])
        pairs = [((force_side, force_point["force"]), (motion_side, motion_point["force_input"]), True),
                 ((motion_side, motion_point["velocity"]), (force_side, force_point["velocity_input"]), True),
                 ((motion_side, motion_point["position"]), (force_side, force_point["position_input"]), False)]
        for (source_sim, output), (target_sim, input_), bond in pairs:
            if not isinstance(output, str) or not isinstance(input_, str):
                raise _refuse(scene, f"couplings.{name}: vector points")
            marker = f" powerBond={quoteattr(name)}" if bond else ""
            causality = (' causality="output"', ' causality="input"') if bond else ("", "")
            connections.append(
                f"\n    <VariableConnection{marker}>"
                f"\n      <Variable simulator={quoteattr(source_sim)} name={quoteattr(output)}{causality[0]}/>"
                f"\n      <Variable simulator={quoteattr(target_sim)} name={quoteattr(input_)}{causality[1]}/>"
                f"\n    </VariableConnection>")
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(f"""<?xml version="1.0" encoding="utf-8"?>
<!-- {scene.name} written as an OSP system structure by tests/interop/scene_osp.py -->
<OspSystemStructure xmlns="{OSP_NAMESPACE}" version="0.1">
  <StartTime>0.0</StartTime>
  <EndTime>{float(manager['duration'])!r}</EndTime>
  <BaseStepSize>{base!r}</BaseStepSize>
  <Algorithm>fixedStep</Algorithm>
  <Simulators>{''.join(simulators)}
  </Simulators>
  <Connections>{''.join(connections)}
  </Connections>
</OspSystemStructure>
""")
    return out
