"""The range an FMU declares for an input (FMI min and max): check-model drives the input inside it, as an FMU may
refuse anything else (crane-fmu's MobileCrane declares pedestal.boom[0] in [3, 3] m and stops on any other value)."""
from __future__ import annotations

import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

import numpy as np
import pytest

from zencosim.examples.write import write_examples
from zencosim.subsystems.integrators import INTEGRATORS
from zencosim.subsystems.models.conformance import _drive, check_component
from zencosim.subsystems.models.external.model import ExternalSettings, ExternalSpec, FmuModel
from zencosim.subsystems.subsystem import Subsystem

pytest.importorskip("fmpy")

LOW, HIGH = 1.5, 2.5  # [N] the declared range of f_in
MASS = 2.0  # [kg]: at rest, a = f_in / m


@pytest.fixture(scope="module")
def ranged(tmp_path_factory) -> Path:
    """The example oscillator FMU with f_in declared in [LOW, HIGH] and its start inside."""
    directory = tmp_path_factory.mktemp("ranges")
    write_examples(directory)
    with zipfile.ZipFile(directory / "oscillator_fmi2.fmu") as archive:
        files = {name: archive.read(name) for name in archive.namelist()}
    root = ET.fromstring(files["modelDescription.xml"])
    for variable in root.iter("ScalarVariable"):
        if variable.get("name") == "f_in":
            variable.find("Real").attrib.update({"min": repr(LOW), "max": repr(HIGH), "start": repr(LOW)})
    files["modelDescription.xml"] = ET.tostring(root, encoding="unicode").encode()
    path = directory / "ranged.fmu"
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, data in files.items():
            archive.writestr(name, data)
    return path


def test_the_declared_range_is_read_in_si(ranged):
    description, _ = FmuModel.describe(ExternalSettings(fmu=str(ranged)), ranged.parent)
    f_in, x_in = description.variables["f_in"], description.variables["x_in"]
    assert (f_in.minimum, f_in.maximum) == (LOW, HIGH) and (x_in.minimum, x_in.maximum) == (-np.inf, np.inf)


def test_check_model_drives_an_input_only_inside_its_declared_range(ranged):
    description, source = FmuModel.describe(ExternalSettings(fmu=str(ranged)), ranged.parent)
    spec = ExternalSpec("fmu", description, source, {"m": MASS}, None, {})
    subsystem = Subsystem("ranged", FmuModel(spec, expose_all=True), INTEGRATORS["own"], 1_000_000)
    inputs = [v.name for v in (description.variables[n] for n in description.inputs)]
    bounds = (np.array([description.variables[n].minimum for n in inputs]),
              np.array([description.variables[n].maximum for n in inputs]))
    outputs = _drive(subsystem, np.random.default_rng(7), 0, 50, 1_000_000, 3, bounds)
    a = outputs[:, [p.name for p in subsystem.outputs].index("a")]
    # k = c = kc = cc = 0 by default: a = f_in / m exactly, f_in constant over each step inside the range
    assert np.all(a >= LOW / MASS) and np.all(a <= HIGH / MASS) and np.ptp(a) > 0.1
    assert check_component(str(ranged), {"m": MASS}) == []
