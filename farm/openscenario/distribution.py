"""Certified sets as OpenSCENARIO 1.2 ParameterValueDistributions over the logical
scenario's parameters (the state variables).

What the standard offers: deterministic distributions (a set or a stepped range of one
parameter; or ``DeterministicMultiParameterDistribution``, a list of value sets that
assign several parameters together) and stochastic ones (one parameter each, drawn
independently: uniform, normal, histogram, ...). A union of boxes is not a product of
independent parameters, so

- a quantified safe set is a ``ValueSetDistribution``: one ``ParameterValueSet`` per box
  centre, the start states the guarantee is about (each box is its centre +- the
  half-width in every state variable, stated in the file header);
- a validated box domain is a product, so it is a ``Stochastic`` distribution of
  independent ``UniformDistribution`` s, exactly the uniform sampling ``validate`` did.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np

from farm.openscenario.elements import el, num
from farm.openscenario.scenario import header


def value_sets(names, centres: np.ndarray, *, scenario_file: str, description: str,
               properties: dict) -> ET.Element:
    """One ParameterValueSet per row of ``centres`` (M, n)."""
    root = el(None, "OpenSCENARIO")
    header(root, 2, description, properties)
    pvd = el(root, "ParameterValueDistribution")
    el(pvd, "ScenarioFile", filepath=scenario_file)
    sets = el(el(el(pvd, "Deterministic"), "DeterministicMultiParameterDistribution"), "ValueSetDistribution")
    for row in np.asarray(centres, dtype=float):
        value_set = el(sets, "ParameterValueSet")
        for name, x in zip(names, row):
            el(value_set, "ParameterAssignment", parameterRef=name, value=num(x))
    return root


def uniform_box(names, lower, upper, *, scenario_file: str, description: str, runs: int, seed: int,
                properties: dict) -> ET.Element:
    """Independent uniforms on [lower_i, upper_i]: uniform on the box."""
    root = el(None, "OpenSCENARIO")
    header(root, 2, description, properties)
    pvd = el(root, "ParameterValueDistribution")
    el(pvd, "ScenarioFile", filepath=scenario_file)
    stochastic = el(pvd, "Stochastic", numberOfTestRuns=int(runs), randomSeed=float(seed))
    for name, lo, hi in zip(names, lower, upper):
        dist = el(stochastic, "StochasticDistribution", parameterName=name)
        el(el(dist, "UniformDistribution"), "Range", lowerLimit=float(lo), upperLimit=float(hi))
    return root
