"""More systems of the peer FMUs (tests/interop/peer_pair.py) for the signal, transformation and unit tests
(tests/interop/test_signals.py): OSP files whose connections are plain signals and one of a simulator alone,
and SSP 1.0 files (``SystemStructure.ssd`` beside the FMUs) of the pair and its variants.

SSP files carry libcosim's OSP annotation for the base step (``osp:FixedStepAlgorithm baseStepSize``), the
start values as an inline ``ssv:ParameterSet`` per component, and connections in the order force,
velocity, position. Each variant is one change: ``own`` pairs ``mass1_own`` (which outputs the force on its
own point, ``f1 = -fc``) with mass2 through a ``ssc:LinearTransformation factor="-1"`` on the force
connection; ``mm`` pairs mass1 with ``mass2_mm`` (x2 in mm) and lets the unit definitions say so (no
transformation: SSP's environment converts units); ``mm_transformed`` is the same pair with the conversion
written out as a ``LinearTransformation factor="0.001"`` (for engines that convert no units).
"""
from __future__ import annotations

from pathlib import Path

from tests.interop.peer_pair import (
    BASE_STEP,
    END_TIME,
    MASS1_START,
    MASS2_START,
    MODELS,
    PAIR,
    build_fmu,
    osp_system,
    variable_connection,
)

SIGNAL_ONLY = variable_connection(*PAIR[0])


def write_osp(directory: Path, simulators: dict[str, tuple[str, dict[str, float]]], connections: str,
              description: str) -> Path:
    """An OspSystemStructure.xml in ``directory`` of ``simulators`` (name -> (peer model, start values)), the
    FMUs built beside it (``peer_pair.osp_system``)."""
    directory.mkdir(parents=True, exist_ok=True)
    for model, _ in simulators.values():
        build_fmu(model, directory / f"{model}.fmu")
    path = directory / "OspSystemStructure.xml"
    path.write_text(osp_system({name: (f"{model}.fmu", start) for name, (model, start) in simulators.items()},
                               connections, description))
    return path


def oneway(directory: Path) -> Path:
    """mass1's coupling force drives mass2 (a signal, no bond); mass1 receives nothing (x2_in = v2_in = 0)."""
    return write_osp(directory, {"mass1": ("mass1", MASS1_START), "mass2": ("mass2", MASS2_START)}, SIGNAL_ONLY,
                     "one signal: mass1.fc drives mass2.fc_in; no power bond")


def alone(directory: Path) -> Path:
    """mass2 alone, coupled to nothing: a free oscillator (fc_in stays 0)."""
    return write_osp(directory, {"mass2": ("mass2", MASS2_START)}, "", "mass2 alone, coupled to nothing")


# SSP -----------------------------------------------------------------------------------------------------

SSP_NAMESPACES = ('xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription" '
                  'xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon" '
                  'xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues" '
                  'xmlns:osp="http://opensimulationplatform.com/SSP/OSPAnnotations"')

SSP_VARIANTS = {  # name -> (force side model, its force output, motion side model, {connection: transformation})
    "plain": ("mass1", "fc", "mass2", {}),
    "own": ("mass1_own", "f1", "mass2", {"force": '<ssc:LinearTransformation factor="-1"/>'}),
    "mm": ("mass1", "fc", "mass2_mm", {}),
    "mm_transformed": ("mass1", "fc", "mass2_mm", {"position": '<ssc:LinearTransformation factor="0.001"/>'}),
}


def _component(name: str, model: str, start: dict[str, float]) -> str:
    connectors = "".join(f'<ssd:Connector name="{v.name}" kind="{v.causality}"><ssc:Real/></ssd:Connector>'
                         for v in MODELS[model] if v.causality in ("input", "output"))
    parameters = "".join(f'<ssv:Parameter name="{n}"><ssv:Real value="{v!r}"/></ssv:Parameter>'
                         for n, v in start.items())
    return (f'\n      <ssd:Component name="{name}" source="{model}.fmu">'
            f"\n        <ssd:Connectors>{connectors}</ssd:Connectors>"
            f"\n        <ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues>"
            f'<ssv:ParameterSet version="1.0" name="start"><ssv:Parameters>{parameters}</ssv:Parameters>'
            f"</ssv:ParameterSet></ssd:ParameterValues></ssd:ParameterBinding></ssd:ParameterBindings>"
            f"\n      </ssd:Component>")


def write_ssd(directory: Path, variant: str) -> Path:
    """The SSP system ``variant`` of :data:`SSP_VARIANTS` as ``directory/SystemStructure.ssd``, the FMUs
    built beside it."""
    force_model, force, motion_model, transformations = SSP_VARIANTS[variant]
    directory.mkdir(parents=True, exist_ok=True)
    for model in (force_model, motion_model):
        build_fmu(model, directory / f"{model}.fmu")
    connections = ""
    for role, (start, output, end, input_) in (("force", ("mass1", force, "mass2", "fc_in")),
                                               ("velocity", ("mass2", "v2", "mass1", "v2_in")),
                                               ("position", ("mass2", "x2", "mass1", "x2_in"))):
        ends = f'startElement="{start}" startConnector="{output}" endElement="{end}" endConnector="{input_}"'
        inside = transformations.get(role)
        connections += f"\n      <ssd:Connection {ends}>{inside}</ssd:Connection>" if inside else \
            f"\n      <ssd:Connection {ends}/>"
    path = directory / "SystemStructure.ssd"
    path.write_text(f"""<?xml version="1.0" encoding="UTF-8"?>
<ssd:SystemStructureDescription name="peer_{variant}" version="1.0" {SSP_NAMESPACES}>
  <ssd:System name="peer_{variant}" description="paper 000 two_mass_damped as the peer pair, SSP variant {variant}">
    <ssd:Elements>{_component("mass1", force_model, MASS1_START)}{_component("mass2", motion_model, MASS2_START)}
    </ssd:Elements>
    <ssd:Connections>{connections}
    </ssd:Connections>
  </ssd:System>
  <ssd:DefaultExperiment startTime="0.0" stopTime="{END_TIME!r}">
    <ssd:Annotations>
      <ssc:Annotation type="com.opensimulationplatform">
        <osp:Algorithm><osp:FixedStepAlgorithm baseStepSize="{BASE_STEP!r}"/></osp:Algorithm>
      </ssc:Annotation>
    </ssd:Annotations>
  </ssd:DefaultExperiment>
</ssd:SystemStructureDescription>
""")
    return path
