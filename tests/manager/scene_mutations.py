"""Mutated scene files: the bundled scenes with keys deleted, types swapped, extreme and non-finite numbers,
unicode and unsafe names, and deep nesting, as a careless user or an attacker would write them.

One mutator for the property test (``tests/manager/test_scene_mutations.py``, driven by hypothesis'
``randoms()``) and for the count of outcomes over many mutations (``benchmarks/mutate_scenes.py``, driven by
``random.Random(seed)``): ``mutated_scene(rng)`` returns the TOML text of one mutant and what was done.
"""
from __future__ import annotations

import copy
import functools
import math
import random
import tomllib
from importlib import resources

import tomli_w

from zencosim.manager.scene.load import bundled_scene_names

NESTING = "__nesting__"  # placeholder replaced by a deeply nested array after the TOML is written
NAMES = ("S*", "a/b", "**", "@x", "", "x?", "x#", "$x", "é", "名前", "a b", "\x1b[31mred", "x\ny", "S1", "S2")
NUMBERS = (0, -1, 1e-15, 1e-9, 1e-300, 1e308, -1e308, 1e7, 2**63, 2**64, 10**30, 0.5, 3, -0.0)
NON_FINITE = (math.nan, math.inf, -math.inf)
SWAPPED = ("text", "", True, False, 1, 1.5, [], [1, "a"], {}, {"x": 1})


@functools.cache
def bundled_documents() -> dict[str, dict]:
    """Every bundled scene as a TOML document (do not mutate: ``mutated_scene`` copies one)."""
    folder = resources.files("zencosim.scenes")
    return {name: tomllib.loads((folder / f"{name}.toml").read_text()) for name in bundled_scene_names()}


def _paths(node, prefix: tuple = ()) -> list[tuple]:
    """Every key path of a document: table keys and array indices, tables included."""
    found = []
    items = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()
    for key, value in items:
        found.append(prefix + (key,))
        found += _paths(value, prefix + (key,))
    return found


def _parent(document: dict, path: tuple):
    node = document
    for key in path[:-1]:
        node = node[key]
    return node


# how often each kind of mutation is drawn: mostly one value changed within its kind, as a user's slip would
KINDS = {"number": 30, "scale": 15, "name": 12, "delete": 12, "swap": 12, "non_finite": 8, "rename": 8, "nesting": 3}


def _mutate_once(document: dict, rng: random.Random) -> str:
    paths = _paths(document)
    leaves = [p for p in paths if not isinstance(_parent(document, p)[p[-1]], (dict, list))]
    path = rng.choice(leaves if leaves and rng.random() < 0.8 else paths)
    parent, key = _parent(document, path), path[-1]
    kind = rng.choices(list(KINDS), weights=list(KINDS.values()))[0]
    where = ".".join(map(str, path))
    if kind == "delete" and isinstance(parent, dict):
        del parent[key]
        return f"deleted {where}"
    if kind == "rename":  # a subsystem's (or another table's) name
        tables = [p for p in paths if len(p) == 2 and p[0] in ("subsystems", "couplings")]
        if tables:
            section, old = rng.choice(tables)
            new = rng.choice(NAMES)
            document[section][new] = document[section].pop(old)
            return f"renamed {section}.{old} to {new!r}"
    if kind == "name":
        parent[key] = rng.choice(NAMES)
    elif kind == "swap":
        parent[key] = copy.deepcopy(rng.choice(SWAPPED))
    elif kind == "number":
        parent[key] = rng.choice(NUMBERS)
    elif kind == "scale" and isinstance(parent[key], (int, float)) and not isinstance(parent[key], bool):
        parent[key] = parent[key] * 10.0 ** rng.choice((-12, -6, -3, -1, 1, 3, 6, 12, 300))
    elif kind == "non_finite":
        parent[key] = rng.choice(NON_FINITE)
    elif kind == "nesting":
        parent[key] = NESTING
    else:  # delete from an array, or scale what is no number
        parent[key] = rng.choice(SWAPPED)
    return f"{kind} {where} = {parent[key]!r}"[:120]


def mutated_scene(rng: random.Random) -> tuple[str, str]:
    """The TOML text of a bundled scene with one to three mutations, and a description of them."""
    documents = bundled_documents()
    name = rng.choice(sorted(documents))
    document = copy.deepcopy(documents[name])
    done = [_mutate_once(document, rng) for _ in range(rng.choices((1, 2, 3), weights=(7, 2, 1))[0])]
    text = tomli_w.dumps(document)
    if NESTING in text:
        depth = rng.choice((10, 100, 1000, 5000))
        text = text.replace(f'"{NESTING}"', "[" * depth + "]" * depth)
    return text, f"{name}: " + "; ".join(done)
