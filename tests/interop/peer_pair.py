"""The "peer pair": paper 000's damped two-mass oscillator as two FMI 2.0 Co-Simulation FMUs built here,
and the OSP system structures that connect them.

The FMUs are compiled with gcc from ``fmus/peer_mass.c`` (fmpy ships the FMI 2.0 headers); their
modelDescription.xml and the C header ``peer_table.h`` are both written from the tables below, so the
value references cannot disagree. Nothing here uses zencosim: the pair is an oracle no one wrote for
zencosim. ``mass1`` holds mass 1 with the coupling spring and damper and outputs ``fc``, the force of the
coupling element on mass 2; ``mass2`` applies its input ``fc_in`` with + (the convention of OSP, SSP and
FMI: a connection copies a value unchanged).

Four systems: {FMUs whose variables declare units, FMUs that declare none} x {plain ``VariableConnection``
elements (the force and velocity ones marked with libcosim's ``powerBond`` attribute, which libcosim
requires to carry ``causality`` attributes), OSP-IS variable groups (``LinearMechanicalPort`` of a
``Force`` and a ``LinearVelocity``, and ``LinearDisplacement``, declared with units in
``<modelName>_OspModelDescription.xml`` beside the FMUs)}.
"""
from __future__ import annotations

import shutil
import subprocess
import tempfile
import xml.etree.ElementTree as ET
import zipfile
from dataclasses import dataclass
from pathlib import Path

HERE = Path(__file__).resolve().parent
SOURCE = HERE / "fmus" / "peer_mass.c"
CFLAGS = ["-shared", "-fPIC", "-O2", "-ffp-contract=off", "-std=c99", "-Wall", "-Werror", "-Wno-unused-parameter"]

# paper 000, two_mass_damped (scenes/two_mass_damped.toml)
BASE_STEP = 0.001  # [s]
END_TIME = 10.0  # [s]
STEPS = 10_000
MASS1_START = {"m": 1.0, "k": 10.0, "c": 0.1, "kc": 100.0, "cc": 0.1, "x0": 0.0, "v0": 100.0}
MASS2_START = {"m": 1.0, "k": 1000.0, "c": 0.1, "x0": 0.0, "v0": -100.0}

UNITS = {"kg": {"kg": 1}, "N/m": {"kg": 1, "s": -2}, "N.s/m": {"kg": 1, "s": -1}, "m": {"m": 1},
         "m/s": {"m": 1, "s": -1}, "N": {"kg": 1, "m": 1, "s": -2}, "mm": {"m": 1, "factor": 0.001},
         # the other domains' variants (DOMAIN_UNITS below)
         "kg.m2": {"kg": 1, "m": 2}, "N.m/rad": {"kg": 1, "m": 2, "s": -2, "rad": -1},
         "N.m.s/rad": {"kg": 1, "m": 2, "s": -1, "rad": -1}, "N.m": {"kg": 1, "m": 2, "s": -2},
         "rad/s": {"rad": 1, "s": -1}, "rad": {"rad": 1},
         "kg/m4": {"kg": 1, "m": -4}, "Pa/m3": {"kg": 1, "m": -4, "s": -2}, "Pa.s/m3": {"kg": 1, "m": -4, "s": -1},
         "Pa": {"kg": 1, "m": -1, "s": -2}, "m3/s": {"m": 3, "s": -1}, "m3": {"m": 3},
         "H": {"kg": 1, "m": 2, "s": -2, "A": -2}, "V/C": {"kg": 1, "m": 2, "s": -4, "A": -2},
         "Ohm": {"kg": 1, "m": 2, "s": -3, "A": -2}, "V": {"kg": 1, "m": 2, "s": -3, "A": -1}, "A": {"A": 1},
         "C": {"A": 1, "s": 1}}


@dataclass(frozen=True)
class Var:
    name: str
    causality: str  # parameter, input, output
    unit: str
    start: float | None = None  # parameters and inputs; the defaults are neutral: the systems set the rest
    depends: tuple[str, ...] = ()  # outputs: the inputs they depend on directly (direct feedthrough)
    initial: tuple[str, ...] = ()  # outputs: the parameters and inputs their initial value depends on


def _mass_parameters() -> tuple[Var, ...]:
    return (Var("m", "parameter", "kg", 1.0), Var("k", "parameter", "N/m", 0.0), Var("c", "parameter", "N.s/m", 0.0))


MODELS: dict[str, tuple[Var, ...]] = {
    "mass1": (*_mass_parameters(),
              Var("kc", "parameter", "N/m", 0.0), Var("cc", "parameter", "N.s/m", 0.0),
              Var("x0", "parameter", "m", 0.0), Var("v0", "parameter", "m/s", 0.0),
              Var("x2_in", "input", "m", 0.0), Var("v2_in", "input", "m/s", 0.0),
              Var("x1", "output", "m", initial=("x0",)), Var("v1", "output", "m/s", initial=("v0",)),
              Var("fc", "output", "N", depends=("x2_in", "v2_in"),
                  initial=("kc", "cc", "x0", "v0", "x2_in", "v2_in"))),
    "mass2": (*_mass_parameters(),
              Var("x0", "parameter", "m", 0.0), Var("v0", "parameter", "m/s", 0.0),
              Var("fc_in", "input", "N", 0.0),
              Var("x2", "output", "m", initial=("x0",)), Var("v2", "output", "m/s", initial=("v0",))),
}
# variants for the signal and SSP tests (tests/interop/test_signals.py), from the same C source:
# mass1_own outputs f1, the force of the coupling element on its OWN mass (-fc; -DPEER_OWN_FORCE), so that
# the force its partner needs is -f1 (an SSP LinearTransformation factor -1); mass2_mm outputs x2 in mm
# (a unit definition with factor 0.001; -DPEER_X_MM), the state and x0 staying in m
MODELS["mass1_own"] = tuple(Var("f1", "output", "N", depends=v.depends, initial=v.initial) if v.name == "fc" else v
                            for v in MODELS["mass1"])
MODELS["mass2_mm"] = tuple(Var("x2", "output", "mm", initial=v.initial) if v.name == "x2" else v
                           for v in MODELS["mass2"])
# and for the fault tests (tests/manager/test_faults.py) mass2_exits, whose doStep calls the C library's exit(0)
# from t = 10 ms (-DPEER_EXIT_AT=0.01)
MODELS["mass2_exits"] = MODELS["mass2"]
BUILD = {"mass1": ("1", ()), "mass2": ("2", ()), "mass1_own": ("1", ("-DPEER_OWN_FORCE",)),
         "mass2_mm": ("2", ("-DPEER_X_MM",)),
         "mass2_exits": ("2", ("-DPEER_EXIT_AT=0.01",))}  # model -> (PEER_MASS, further compiler flags)
GUID = {"mass1": "{a3c5e0f2-5d0b-4c52-9a1e-peer00mass01}", "mass2": "{a3c5e0f2-5d0b-4c52-9a1e-peer00mass02}",
        "mass1_own": "{a3c5e0f2-5d0b-4c52-9a1e-peer00mass11}", "mass2_mm": "{a3c5e0f2-5d0b-4c52-9a1e-peer00mass22}",
        "mass2_exits": "{a3c5e0f2-5d0b-4c52-9a1e-peer00mass32}"}
DESCRIPTION = {"mass1": "mass 1 of paper 000's two_mass_damped with the coupling spring-damper; "
                        "fc is the force of the coupling element on mass 2",
               "mass2": "mass 2 of paper 000's two_mass_damped; fc_in is the force on it",
               "mass1_own": "mass 1 of paper 000's two_mass_damped with the coupling spring-damper; "
                            "f1 is the force of the coupling element on mass 1 (its own point)",
               "mass2_mm": "mass 2 of paper 000's two_mass_damped; fc_in is the force on it; x2 in mm",
               "mass2_exits": "mass 2 of paper 000's two_mass_damped whose doStep ends the process from t = 10 ms"}

# the same equations in the other domains of power bonds (tests/interop/test_domains_osp.py): the C source is
# the same (units are the modelDescription's only), the units those of an inertia, a stiffness, a damping, an
# effort, a flow and a displacement: rotational (kg.m2, N.m/rad, N.m.s/rad; N.m, rad/s, rad), hydraulic
# (inertance kg/m4, Pa/m3, Pa.s/m3; Pa, m3/s, m3), electrical (inductance H, elastance V/C, resistance Ohm;
# V, A, C). mass1_<domain> and mass2_<domain>.
DOMAIN_UNITS = {  # domain -> units of (m, k and kc, c and cc, effort, flow, displacement)
    "rotational": ("kg.m2", "N.m/rad", "N.m.s/rad", "N.m", "rad/s", "rad"),
    "hydraulic": ("kg/m4", "Pa/m3", "Pa.s/m3", "Pa", "m3/s", "m3"),
    "electrical": ("H", "V/C", "Ohm", "V", "A", "C"),
}
_ROLE_OF = {"m": 0, "k": 1, "kc": 1, "c": 2, "cc": 2, "fc": 3, "fc_in": 3, "v0": 4, "v2_in": 4, "v1": 4, "v2": 4,
            "x0": 5, "x2_in": 5, "x1": 5, "x2": 5}
for _number, (_domain, _units) in enumerate(DOMAIN_UNITS.items(), start=1):
    for _mass in ("1", "2"):
        _model = f"mass{_mass}_{_domain}"
        MODELS[_model] = tuple(Var(v.name, v.causality, _units[_ROLE_OF[v.name]], v.start, v.depends, v.initial)
                               for v in MODELS[f"mass{_mass}"])
        BUILD[_model] = (_mass, ())
        GUID[_model] = f"{{a3c5e0f2-5d0b-4c52-9a1e-peer0{_number}mass0{_mass}}}"
        DESCRIPTION[_model] = f"{DESCRIPTION[f'mass{_mass}']}; in {_domain} units ({', '.join(_units[3:])})"


def model_identifier(model: str) -> str:
    return f"peer_{model}"


def fmi_headers() -> Path:
    import fmpy

    return Path(fmpy.__file__).parent / "c-code"


def c_table(model: str) -> str:
    variables = MODELS[model]
    starts = ", ".join(repr(float(v.start or 0.0)) for v in variables)
    kinds = ", ".join({"input": "1", "parameter": "0"}.get(v.causality, "-1") for v in variables)
    lines = [f"#define VR_{v.name} {vr}" for vr, v in enumerate(variables)]
    lines += [f"#define N_VARIABLES {len(variables)}", f"#define START_VALUES {{{starts}}}",
              f"#define IS_INPUT {{{kinds}}}", f'#define GUID "{GUID[model]}"']
    return "\n".join(lines) + "\n"


def model_description(model: str, units: bool) -> str:
    variables = MODELS[model]
    index = {v.name: str(i) for i, v in enumerate(variables, start=1)}
    root = ET.Element("fmiModelDescription", {
        "fmiVersion": "2.0", "modelName": model_identifier(model), "guid": GUID[model],
        "description": DESCRIPTION[model], "generationTool": "tests/interop/peer_pair.py",
        "variableNamingConvention": "flat", "numberOfEventIndicators": "0"})
    ET.SubElement(root, "CoSimulation", {"modelIdentifier": model_identifier(model),
                                         "canHandleVariableCommunicationStepSize": "true",
                                         "canGetAndSetFMUstate": "false", "canSerializeFMUstate": "false",
                                         "canNotUseMemoryManagementFunctions": "true"})
    if units:
        definitions = ET.SubElement(root, "UnitDefinitions")
        for name in sorted({v.unit for v in variables}):
            ET.SubElement(ET.SubElement(definitions, "Unit", name=name), "BaseUnit",
                          {k: str(e) for k, e in UNITS[name].items()})
    ET.SubElement(root, "DefaultExperiment", startTime="0.0", stopTime=repr(END_TIME), stepSize=repr(BASE_STEP))
    scalars = ET.SubElement(root, "ModelVariables")
    for vr, v in enumerate(variables):
        attributes = {"name": v.name, "valueReference": str(vr), "causality": v.causality,
                      "variability": "fixed" if v.causality == "parameter" else "continuous"}
        if v.causality == "parameter":
            attributes["initial"] = "exact"
        real = {"unit": v.unit} if units else {}
        if v.start is not None:
            real["start"] = repr(float(v.start))
        ET.SubElement(ET.SubElement(scalars, "ScalarVariable", attributes), "Real", real)
    structure = ET.SubElement(root, "ModelStructure")
    outputs = [v for v in variables if v.causality == "output"]
    for section, dependencies in (("Outputs", "depends"), ("InitialUnknowns", "initial")):
        element = ET.SubElement(structure, section)
        for v in outputs:
            ET.SubElement(element, "Unknown", index=index[v.name],
                          dependencies=" ".join(index[d] for d in getattr(v, dependencies)))
    ET.indent(root)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def build_fmu(model: str, out: Path, units: bool = True) -> Path:
    """Compile ``model`` (a key of :data:`MODELS`) into the FMU ``out``; RuntimeError with gcc's message."""
    gcc = shutil.which("gcc")
    if gcc is None:
        raise RuntimeError("building the peer FMUs needs gcc")
    identifier = model_identifier(model)
    with tempfile.TemporaryDirectory(prefix="peer-fmu-") as tmp:
        build = Path(tmp)
        (build / "peer_table.h").write_text(c_table(model))
        library = build / f"{identifier}.so"
        mass, flags = BUILD[model]
        command = [gcc, *CFLAGS, f"-DPEER_MASS={mass}", *flags, f"-I{build}", f"-I{fmi_headers()}", "-o",
                   str(library), str(SOURCE), "-lm"]
        done = subprocess.run(command, check=False, capture_output=True, text=True)
        if done.returncode != 0:
            raise RuntimeError(f"gcc could not compile {SOURCE} for {model}:\n{done.stderr.strip()}")
        out.parent.mkdir(parents=True, exist_ok=True)
        with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as fmu:
            fmu.writestr("modelDescription.xml", model_description(model, units))
            fmu.write(library, f"binaries/linux64/{identifier}.so")
    return out


# OSP system structures -----------------------------------------------------------------------------

OSP_NAMESPACE = "http://opensimulationplatform.com/MSMI/OSPSystemStructure"

def variable_connection(source: tuple[str, str], target: tuple[str, str], bond: str | None = None) -> str:
    """An OSP ``VariableConnection`` from ``(simulator, variable)`` ``source`` to ``target``; with ``bond``, marked
    as one side of that power bond (libcosim then wants each variable's causality too)."""
    marked = bond is not None
    attributes = [f' causality="{c}"' if marked else "" for c in ("output", "input")]
    bond_attribute = f' powerBond="{bond}"' if marked else ""
    return (f"\n    <VariableConnection{bond_attribute}>"
            + "".join(f'\n      <Variable simulator="{simulator}" name="{name}"{attribute}/>'
                      for (simulator, name), attribute in zip((source, target), attributes))
            + "\n    </VariableConnection>")


def ecco_configuration(parameters: dict[str, object]) -> str:
    """An OSP ``EccoConfiguration`` element (libcosim's ecco algorithm) of ``parameters``: element name -> value,
    in order."""
    return ("\n  <EccoConfiguration>" + "".join(f"\n    <{name}>{value}</{name}>" for name, value in parameters.items())
            + "\n  </EccoConfiguration>\n")


PAIR = ((("mass1", "fc"), ("mass2", "fc_in")), (("mass2", "v2"), ("mass1", "v2_in")))  # force, velocity
DISPLACEMENT = variable_connection(("mass2", "x2"), ("mass1", "x2_in"))
PLAIN_CONNECTIONS = "".join(variable_connection(*ends, bond="c") for ends in PAIR) + DISPLACEMENT
UNMARKED_CONNECTIONS = "".join(variable_connection(*ends) for ends in PAIR) + DISPLACEMENT

GROUP_CONNECTIONS = """
    <VariableGroupConnection>
      <VariableGroup simulator="mass1" name="coupling"/>
      <VariableGroup simulator="mass2" name="m2"/>
    </VariableGroupConnection>
    <VariableGroupConnection>
      <VariableGroup simulator="mass2" name="position"/>
      <VariableGroup simulator="mass1" name="position input"/>
    </VariableGroupConnection>"""

OSP_MODEL_DESCRIPTIONS = {  # OSP-IS: LinearMechanicalPort = Force + LinearVelocity; units declared here
    "mass1": """<?xml version="1.0" encoding="utf-8"?>
<OspModelDescription xmlns="https://open-simulation-platform.com/OspModelDescription/1.0.0" version="1.0">
  <UnitDefinitions>
    <Unit name="N"><BaseUnit kg="1" m="1" s="-2"/></Unit>
    <Unit name="m/s"><BaseUnit m="1" s="-1"/></Unit>
    <Unit name="m"><BaseUnit m="1"/></Unit>
  </UnitDefinitions>
  <VariableGroups>
    <LinearMechanicalPort name="coupling">
      <Force name="coupling force"><Variable ref="fc" unit="N"/></Force>
      <LinearVelocity name="coupling velocity"><Variable ref="v2_in" unit="m/s"/></LinearVelocity>
    </LinearMechanicalPort>
    <LinearDisplacement name="position input"><Variable ref="x2_in" unit="m"/></LinearDisplacement>
  </VariableGroups>
</OspModelDescription>
""",
    "mass2": """<?xml version="1.0" encoding="utf-8"?>
<OspModelDescription xmlns="https://open-simulation-platform.com/OspModelDescription/1.0.0" version="1.0">
  <UnitDefinitions>
    <Unit name="N"><BaseUnit kg="1" m="1" s="-2"/></Unit>
    <Unit name="m/s"><BaseUnit m="1" s="-1"/></Unit>
    <Unit name="m"><BaseUnit m="1"/></Unit>
  </UnitDefinitions>
  <VariableGroups>
    <LinearMechanicalPort name="m2">
      <Force name="m2 force"><Variable ref="fc_in" unit="N"/></Force>
      <LinearVelocity name="m2 velocity"><Variable ref="v2" unit="m/s"/></LinearVelocity>
    </LinearMechanicalPort>
    <LinearDisplacement name="position"><Variable ref="x2" unit="m"/></LinearDisplacement>
  </VariableGroups>
</OspModelDescription>
""",
}

CONNECTIONS = {"plain": PLAIN_CONNECTIONS, "groups": GROUP_CONNECTIONS, "unmarked": UNMARKED_CONNECTIONS}


def _initial_values(values: dict[str, float]) -> str:
    return "".join(f'\n        <InitialValue variable="{name}"><Real value="{value!r}"/></InitialValue>'
                   for name, value in values.items())


def osp_system(simulators: dict[str, tuple[str, dict[str, float]]], connections: str, description: str) -> str:
    """An OspSystemStructure.xml of ``simulators`` (name -> (FMU file, start values)) joined by ``connections`` (the
    elements of ``<Connections>``; "": none): fixed step, BaseStepSize 1 ms, 0 to 10 s."""
    elements = "".join(
        f'\n    <Simulator name="{name}" source="{source}" stepSize="{BASE_STEP!r}">'
        f"\n      <InitialValues>{_initial_values(start)}\n      </InitialValues>\n    </Simulator>"
        for name, (source, start) in simulators.items())
    connections_element = f"\n  <Connections>{connections}\n  </Connections>" if connections else ""
    return f"""<?xml version="1.0" encoding="utf-8"?>
<!-- {description} -->
<OspSystemStructure xmlns="{OSP_NAMESPACE}" version="0.1">
  <StartTime>0.0</StartTime>
  <EndTime>{END_TIME!r}</EndTime>
  <BaseStepSize>{BASE_STEP!r}</BaseStepSize>
  <Algorithm>fixedStep</Algorithm>
  <Simulators>{elements}
  </Simulators>{connections_element}
</OspSystemStructure>
"""


SYSTEMS = {  # name -> (units declared by the FMUs, connections)
    "plain": (True, "plain"),
    "plain_nounits": (False, "plain"),
    "groups": (True, "groups"),
    "groups_nounits": (False, "groups"),
    "unmarked": (True, "unmarked"),
}


def write_system(directory: Path, name: str, mass2: str = "mass2") -> Path:
    """Build the two FMUs into ``directory`` and write the system ``name`` of :data:`SYSTEMS` there
    (with the OSP model descriptions for groups); return its OspSystemStructure.xml. ``mass2``: the model that
    simulator mass2 runs (a variant of mass2 in a plain system)."""
    units, connections = SYSTEMS[name]
    directory.mkdir(parents=True, exist_ok=True)
    for model in ("mass1", "mass2"):
        build_fmu(mass2 if model == "mass2" else model, directory / f"{model}.fmu", units)
        if connections == "groups":
            (directory / f"{model_identifier(model)}_OspModelDescription.xml").write_text(
                OSP_MODEL_DESCRIPTIONS[model])
    description = (f"paper 000 two_mass_damped as the peer pair: {'units declared' if units else 'no units'}, "
                   f"{connections} connections")
    path = directory / "OspSystemStructure.xml"
    path.write_text(osp_system({"mass1": ("mass1.fmu", MASS1_START), "mass2": ("mass2.fmu", MASS2_START)},
                               CONNECTIONS[connections], description))
    return path
