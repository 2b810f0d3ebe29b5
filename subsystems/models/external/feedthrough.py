"""The ``feedthrough`` key of an external model: what a component's outputs depend on at the same instant, as the
scene states it where the component omits it or gets it wrong.

``feedthrough = { out = ["in", …] }`` says that output ``out`` depends directly on those inputs; an output the
table does not list depends on none, so ``feedthrough = {}`` says no output feeds through. Without the key an
FMU's ``ModelStructure`` decides, and an output it lists without ``dependencies`` depends on every input (FMI 2.0
§2.2.8, FMI 3.0 §2.4.8). Names are the component's variable names.
"""
from __future__ import annotations

from dataclasses import replace
from typing import Any

from zencosim.subsystems.models.external.component import ComponentDescription
from zencosim.subsystems.params import Problems

EXAMPLE = 'feedthrough = { y = ["u"] } (output y depends on input u at the same instant; {}: no output does)'


def read_feedthrough(table: Any, description: ComponentDescription, key: str,
                     problems: Problems) -> dict[str, tuple[str, ...]] | None:
    """The ``feedthrough`` table as output -> inputs (None: no table); every unknown variable, output that is not
    an output and input that is not an input recorded under ``key``."""
    if table is None:
        return None
    if not isinstance(table, dict):
        problems.add(key, f"expected a table of output = [inputs], e.g. {EXAMPLE}; got {table!r}")
        return None
    stated = {}
    for output, inputs in table.items():
        where = f"{key}.{output}"
        problem = _causality_problem(output, "output", description)
        if problem is not None:
            problems.add(where, problem)
            continue
        if not isinstance(inputs, list) or not all(isinstance(name, str) for name in inputs):
            problems.add(where, f"expected a list of input variables, e.g. {EXAMPLE}; got {inputs!r}")
            continue
        for name in inputs:
            problem = _causality_problem(name, "input", description)
            if problem is not None:
                problems.add(where, problem)
        stated[output] = tuple(dict.fromkeys(inputs))
    return stated


def apply_feedthrough(stated: dict[str, tuple[str, ...]] | None, description: ComponentDescription
                      ) -> ComponentDescription:
    """The description with every output's direct dependence as ``stated`` says (an output it does not list: none);
    unchanged without a statement."""
    if stated is None:
        return description
    variables = {name: replace(v, depends_on=stated.get(name, ())) if v.causality == "output" else v
                 for name, v in description.variables.items()}
    return replace(description, variables=variables)


def _causality_problem(name: str, causality: str, description: ComponentDescription) -> str | None:
    """Why ``name`` is not one of the component's variables of ``causality`` (None: it is)."""
    variable = description.variables.get(name)
    names = [n for n, v in description.variables.items() if v.causality == causality]
    if variable is None:
        return (f"the {description.kind} has no variable {name!r}; its {causality}s: "
                f"{', '.join(names) or '(none)'}")
    if variable.causality != causality:
        return f"{name} is {variable.causality}, not an {causality}; its {causality}s: {', '.join(names) or '(none)'}"
    return None
