"""Build the example oscillator FMU from its C source: ``build_fmu(Path("osc.fmu"))``.

One point mass on a line, with a spring and damper to ground, a coupling spring-damper towards a
"terminal" whose motion arrives as inputs, and an applied input force (the model is described in
``oscillator_fmi2.c``). The variables are listed once, in :data:`VARIABLES`: the modelDescription.xml
and the C header that gives the sources their value references and start values
(``oscillator_table.h``, written into the temporary build folder) are both generated from that table.

Building needs gcc and fmpy (for the FMI headers it ships in ``fmpy/c-code``).
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

MODEL_NAME = "zencosim oscillator"
GENERATION_TOOL = "zencosim.examples.fmus.build"
MODEL_IDENTIFIER = {2: "zencosim_oscillator", 3: "zencosim_oscillator3"}
INSTANTIATION_TOKEN = {2: "{zencosim-oscillator-fmi2-2}", 3: "{zencosim-oscillator-fmi3-2}"}
PLATFORM = {2: "linux64", 3: "x86_64-linux"}  # the binaries/ folder of a 64-bit Linux library
SOURCE = {2: HERE / "oscillator_fmi2.c", 3: HERE / "oscillator_fmi3.c"}
CFLAGS = ["-shared", "-fPIC", "-O2", "-ffp-contract=off", "-std=c99", "-Wall", "-Werror"]

# unit name -> exponents of the SI base units (factor 1, offset 0 for all of them)
UNITS: dict[str, dict[str, int]] = {
    "N": {"kg": 1, "m": 1, "s": -2},
    "m": {"m": 1},
    "m/s": {"m": 1, "s": -1},
    "m/s2": {"m": 1, "s": -2},
    "kg": {"kg": 1},
    "N/m": {"kg": 1, "s": -2},
    "N.s/m": {"kg": 1, "s": -1},
    "1/kg": {"kg": -1},
    "J": {"kg": 1, "m": 2, "s": -2},
    "s": {"s": 1},
}


@dataclass(frozen=True)
class Variable:
    """One Real (FMI 2.0) / Float64 (FMI 3.0) variable; its value reference is its position in VARIABLES.

    ``uses`` (outputs only) names what the output's equation reads: parameters, inputs and the
    continuous states ``x`` and ``v``; the ModelStructure's dependencies are derived from it.
    ``derivative_of`` names the state whose derivative this variable is.
    """

    name: str
    causality: str  # "independent", "parameter", "input" or "output"
    unit: str
    description: str
    start: float | None = None  # parameters and inputs
    uses: tuple[str, ...] = ()
    derivative_of: str | None = None


VARIABLES: tuple[Variable, ...] = (
    Variable("time", "independent", "s", "simulation time"),
    Variable("m", "parameter", "kg", "mass", 1.0),
    Variable("k", "parameter", "N/m", "stiffness of the spring to ground", 0.0),
    Variable("c", "parameter", "N.s/m", "damping coefficient of the damper to ground", 0.0),
    Variable("kc", "parameter", "N/m", "stiffness of the coupling spring to the terminal", 0.0),
    Variable("cc", "parameter", "N.s/m", "damping coefficient of the coupling damper to the terminal", 0.0),
    Variable("x0", "parameter", "m", "initial position", 0.0),
    Variable("v0", "parameter", "m/s", "initial velocity", 0.0),
    Variable("fail_at", "parameter", "s", "a doStep starting at or after this time fails (fault injection)", 1e300),
    Variable("x_in", "input", "m", "position of the terminal", 0.0),
    Variable("v_in", "input", "m/s", "velocity of the terminal", 0.0),
    Variable("f_in", "input", "N", "applied force", 0.0),
    Variable("x", "output", "m", "position (continuous state)", uses=("x",)),
    Variable("v", "output", "m/s", "velocity (continuous state)", uses=("v",), derivative_of="x"),
    Variable("a", "output", "m/s2", "acceleration (a = (-k*x - c*v - fc + f_in)/m)",
             uses=("m", "k", "c", "kc", "cc", "x", "v", "x_in", "v_in", "f_in"), derivative_of="v"),
    Variable("fc", "output", "N",
             "force of the coupling element on the terminal (fc = kc*(x - x_in) + cc*(v - v_in))",
             uses=("kc", "cc", "x", "v", "x_in", "v_in")),
    Variable("inverse_mass", "output", "1/kg", "1/m", uses=("m",)),
    Variable("E", "output", "J", "energy in the mass, the spring to ground and the coupling spring",
             uses=("m", "k", "kc", "x", "v", "x_in")),
)
STATES = {"x": "x0", "v": "v0"}  # continuous state -> the parameter that gives its start


def build_fmu(out: Path, fmi_version: int = 2, interfaces: tuple[str, ...] = ("cs",),
              can_get_and_set_state: bool = True, can_serialize_state: bool = True) -> Path:
    """Compile the oscillator for FMI ``fmi_version`` (2 or 3) with gcc and zip it into the FMU ``out``.

    ``interfaces`` are the FMI kinds the modelDescription offers: any of "cs" (Co-Simulation) and
    "me" (Model Exchange) for FMI 2.0 (one binary implements both), only "cs" for FMI 3.0.
    ``can_get_and_set_state`` and ``can_serialize_state`` are declared in the modelDescription and
    compiled into the binary (the state functions return an error where the FMU says it cannot);
    without get/set there is no serialization either. Raises ValueError for an unsupported
    combination and RuntimeError, with gcc's message, when compiling fails. Returns ``out``.
    """
    out = Path(out)
    if fmi_version not in (2, 3):
        raise ValueError(f"fmi_version must be 2 or 3, not {fmi_version!r}")
    offered = {"cs", "me"} if fmi_version == 2 else {"cs"}
    if not interfaces or not set(interfaces) <= offered:
        raise ValueError(f"interfaces for FMI {fmi_version}.0 must be a non-empty subset of {sorted(offered)}, "
                         f"not {interfaces!r}")
    can_serialize_state = can_serialize_state and can_get_and_set_state
    identifier = MODEL_IDENTIFIER[fmi_version]

    with tempfile.TemporaryDirectory(prefix="zencosim-fmu-") as tmp:
        build_dir = Path(tmp)
        (build_dir / "oscillator_table.h").write_text(
            c_table(fmi_version, can_get_and_set_state, can_serialize_state))
        library = build_dir / f"{identifier}.so"
        _compile(SOURCE[fmi_version], library, [build_dir, fmi_headers()])
        description = model_description(fmi_version, tuple(interfaces), can_get_and_set_state, can_serialize_state)
        out.parent.mkdir(parents=True, exist_ok=True)
        with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as fmu:
            fmu.writestr("modelDescription.xml", description)
            fmu.write(library, f"binaries/{PLATFORM[fmi_version]}/{identifier}.so")
    return out


def fmi_headers() -> Path:
    """The folder of FMI 2.0 and 3.0 C headers that fmpy ships (``fmpy/c-code``)."""
    import fmpy

    return Path(fmpy.__file__).parent / "c-code"


def _compile(source: Path, library: Path, include_dirs: list[Path]) -> None:
    """Compile the C file ``source`` into the shared library ``library`` with gcc.

    Raises RuntimeError with gcc's stderr if gcc is missing or reports an error.
    """
    gcc = shutil.which("gcc")
    if gcc is None:
        raise RuntimeError("building an example FMU needs gcc, which is not on PATH")
    command = [gcc, *CFLAGS, *(f"-I{d}" for d in include_dirs), "-o", str(library), str(source), "-lm"]
    done = subprocess.run(command, check=False, capture_output=True, text=True)
    if done.returncode != 0:
        raise RuntimeError(f"gcc could not compile {source} (exit status {done.returncode}):\n{done.stderr.strip()}")


def c_table(fmi_version: int, can_get_and_set_state: bool, can_serialize_state: bool) -> str:
    """The C header ``oscillator_table.h``: value references, start values, causalities, token, capabilities."""
    lines = ["/* Generated by zencosim/examples/fmus/build.py from its table VARIABLES: do not edit. */"]
    lines += [f"#define VR_{v.name} {vr}" for vr, v in enumerate(VARIABLES)]
    starts = ", ".join(repr(float(v.start or 0.0)) for v in VARIABLES)  # repr: the shortest exact decimal
    causalities = ", ".join(v.causality.upper() for v in VARIABLES)
    lines += [
        f"#define N_VARIABLES {len(VARIABLES)}",
        f"#define START_VALUES {{{starts}}}",
        "enum { INDEPENDENT, PARAMETER, INPUT, OUTPUT };",
        f"#define CAUSALITIES {{{causalities}}}",
        f'#define INSTANTIATION_TOKEN "{INSTANTIATION_TOKEN[fmi_version]}"',
        f"#define CAN_GET_AND_SET_STATE {int(can_get_and_set_state)}",
        f"#define CAN_SERIALIZE_STATE {int(can_serialize_state)}",
    ]
    return "\n".join(lines) + "\n"


def model_description(fmi_version: int, interfaces: tuple[str, ...], can_get_and_set_state: bool,
                      can_serialize_state: bool) -> str:
    """The modelDescription.xml of the oscillator, generated from VARIABLES and UNITS."""
    fmi2 = fmi_version == 2
    root = ET.Element("fmiModelDescription", {
        "fmiVersion": "2.0" if fmi2 else "3.0",
        "modelName": MODEL_NAME,
        ("guid" if fmi2 else "instantiationToken"): INSTANTIATION_TOKEN[fmi_version],
        "description": "a point mass with a spring and damper to ground and a spring-damper coupling to a terminal",
        "generationTool": GENERATION_TOOL,
        "variableNamingConvention": "flat",
        **({"numberOfEventIndicators": "0"} if fmi2 else {}),
    })
    state = "FMUstate" if fmi2 else "FMUState"
    capabilities = {f"canGetAndSet{state}": _xml_bool(can_get_and_set_state),
                    f"canSerialize{state}": _xml_bool(can_serialize_state)}
    if fmi2:
        capabilities["canNotUseMemoryManagementFunctions"] = "true"  # the C code allocates with calloc
    if "me" in interfaces:
        ET.SubElement(root, "ModelExchange", {"modelIdentifier": MODEL_IDENTIFIER[fmi_version],
                                              "completedIntegratorStepNotNeeded": "true", **capabilities})
    if "cs" in interfaces:
        ET.SubElement(root, "CoSimulation", {"modelIdentifier": MODEL_IDENTIFIER[fmi_version],
                                             "canHandleVariableCommunicationStepSize": "true", **capabilities})

    units = ET.SubElement(root, "UnitDefinitions")
    for name, exponents in UNITS.items():
        ET.SubElement(ET.SubElement(units, "Unit", name=name), "BaseUnit", {k: str(e) for k, e in exponents.items()})

    variables = ET.SubElement(root, "ModelVariables")
    for vr, v in enumerate(VARIABLES):
        attributes = {"name": v.name, "valueReference": str(vr), "description": v.description,
                      "causality": v.causality, "variability": _variability(v)}
        if v.causality in ("parameter", "output"):
            attributes["initial"] = "exact" if v.causality == "parameter" else "calculated"
        value = {"unit": v.unit}
        if v.start is not None:
            value["start"] = repr(float(v.start))
        if v.derivative_of is not None:
            value["derivative"] = str(_ref(v.derivative_of, fmi2))
        if fmi2:
            ET.SubElement(ET.SubElement(variables, "ScalarVariable", attributes), "Real", value)
        else:
            ET.SubElement(variables, "Float64", {**attributes, **value})

    structure = ET.SubElement(root, "ModelStructure")
    outputs = [v for v in VARIABLES if v.causality == "output"]
    derivatives = [v for v in VARIABLES if v.derivative_of is not None]
    sections = [("Outputs", "Output", outputs, _direct_dependencies),
                ("Derivatives", "ContinuousStateDerivative", derivatives, _direct_dependencies),
                ("InitialUnknowns", "InitialUnknown", outputs, _initial_dependencies)]
    for fmi2_section, fmi3_element, unknowns, dependencies in sections:
        parent = ET.SubElement(structure, fmi2_section) if fmi2 else structure
        for v in unknowns:
            attributes = {"index" if fmi2 else "valueReference": str(_ref(v.name, fmi2)),
                          "dependencies": " ".join(str(_ref(d, fmi2)) for d in dependencies(v))}
            ET.SubElement(parent, "Unknown" if fmi2 else fmi3_element, attributes)

    ET.indent(root)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def _variability(v: Variable) -> str:
    return "fixed" if v.causality == "parameter" else "continuous"


def _xml_bool(value: bool) -> str:
    return "true" if value else "false"


def _ref(name: str, fmi2: bool) -> int:
    """How the ModelStructure refers to a variable: its 1-based index (FMI 2.0) or value reference (FMI 3.0)."""
    vr = [v.name for v in VARIABLES].index(name)
    return vr + 1 if fmi2 else vr


def _causality(name: str) -> str:
    return next(v.causality for v in VARIABLES if v.name == name)


def _direct_dependencies(v: Variable) -> list[str]:
    """The knowns an output or derivative depends on while simulating: continuous states and inputs."""
    return sorted((d for d in v.uses if d in STATES or _causality(d) == "input"), key=lambda d: _ref(d, False))


def _initial_dependencies(v: Variable) -> list[str]:
    """The knowns an initial unknown depends on: inputs and parameters (a state starts at its parameter)."""
    used = {STATES.get(d, d) for d in v.uses}
    return sorted((d for d in used if _causality(d) in ("input", "parameter")), key=lambda d: _ref(d, False))
