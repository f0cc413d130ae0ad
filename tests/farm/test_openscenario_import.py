"""OpenSCENARIO in: a logical scenario's ParameterValueDistribution, mapped to state
variables by [validate.openscenario], is the claimed domain of validate. The files are
real OpenSCENARIO 1.2 (checked against the ASAM schema), the validations real runs."""

import subprocess
import sys
import textwrap

import numpy as np
import pytest

from coordinator.domain import DomainError
from farm import validate
from farm.config import ConfigError
from farm.openscenario.distribution import value_sets
from farm.openscenario.elements import write_xml
from farm.openscenario.ranges import parameter_ranges
from xosc_reading import osc12, schema_errors


HEADER = '<?xml version="1.0" encoding="UTF-8"?>\n<OpenSCENARIO>\n  <FileHeader revMajor="1" revMinor="2" ' \
         'date="2024-05-01T12:00:00" description="car following, logical" author="another tool"/>\n'


def distribution(body: str) -> str:
    return HEADER + textwrap.indent(textwrap.dedent(f"""\
        <ParameterValueDistribution>
          <ScenarioFile filepath="following.xosc"/>
        {textwrap.indent(textwrap.dedent(body), '  ')}
        </ParameterValueDistribution>
        """), "  ") + "</OpenSCENARIO>\n"


DETERMINISTIC = distribution("""\
    <Deterministic>
      <DeterministicSingleParameterDistribution parameterName="EgoSpeed">
        <DistributionRange stepWidth="1.0"><Range lowerLimit="8.0" upperLimit="14.0"/></DistributionRange>
      </DeterministicSingleParameterDistribution>
      <DeterministicSingleParameterDistribution parameterName="LeadSpeed">
        <DistributionSet><Element value="6"/><Element value="12.5"/><Element value="10"/></DistributionSet>
      </DeterministicSingleParameterDistribution>
      <DeterministicSingleParameterDistribution parameterName="Gap">
        <DistributionRange stepWidth="5"><Range lowerLimit="40" upperLimit="70"/></DistributionRange>
      </DeterministicSingleParameterDistribution>
      <DeterministicSingleParameterDistribution parameterName="Weather">
        <DistributionSet><Element value="rain"/><Element value="fog"/></DistributionSet>
      </DeterministicSingleParameterDistribution>
    </Deterministic>""")

STOCHASTIC = distribution("""\
    <Stochastic numberOfTestRuns="100" randomSeed="3">
      <StochasticDistribution parameterName="EgoSpeed">
        <NormalDistribution expectedValue="11" variance="2"><Range lowerLimit="9" upperLimit="13"/></NormalDistribution>
      </StochasticDistribution>
      <StochasticDistribution parameterName="LeadSpeed">
        <Histogram>
          <Bin weight="0.5"><Range lowerLimit="4" upperLimit="8"/></Bin>
          <Bin weight="0.5"><Range lowerLimit="8" upperLimit="15"/></Bin>
        </Histogram>
      </StochasticDistribution>
      <StochasticDistribution parameterName="Gap">
        <UniformDistribution><Range lowerLimit="45" upperLimit="69.5"/></UniformDistribution>
      </StochasticDistribution>
      <StochasticDistribution parameterName="Cars">
        <ProbabilityDistributionSet><Element value="1" weight="1"/><Element value="3" weight="2"/></ProbabilityDistributionSet>
      </StochasticDistribution>
      <StochasticDistribution parameterName="Drift">
        <NormalDistribution expectedValue="0" variance="1"/>
      </StochasticDistribution>
    </Stochastic>""")

MAP = {"v0": "EgoSpeed", "v1": "LeadSpeed", "p10": "Gap"}


def config(path, mapping=MAP, **validate_section):
    return {"scenario": {"name": "lead-follow", "sv_policy": "idm"},
            "validate": {"epsilon": 0.02, "openscenario": {"file": str(path), "map": mapping}, **validate_section},
            "farm": {"executor": "local"}}


@pytest.fixture
def files(tmp_path):
    out = {}
    for name, text in [("deterministic", DETERMINISTIC), ("stochastic", STOCHASTIC)]:
        (tmp_path / f"{name}.xosc").write_text(text)
        assert schema_errors(osc12(), tmp_path / f"{name}.xosc") == []  # what another tool would write
        out[name] = tmp_path / f"{name}.xosc"
    return out


def test_each_kind_of_distribution_gives_its_range(files):
    assert parameter_ranges(files["deterministic"], only=set(MAP.values())) == {
        "EgoSpeed": (8.0, 14.0), "LeadSpeed": (6.0, 12.5), "Gap": (40.0, 70.0)}
    assert parameter_ranges(files["stochastic"], only={"EgoSpeed", "LeadSpeed", "Gap", "Cars"}) == {
        "EgoSpeed": (9.0, 13.0), "LeadSpeed": (4.0, 15.0), "Gap": (45.0, 69.5), "Cars": (1.0, 3.0)}


def test_the_mapped_ranges_are_the_claimed_domain_of_validate(files):
    """Validating from the file is validating the same box given as [validate] domain:
    the same runs, the same verdict."""
    for name, box in [("deterministic", {"v0": [8.0, 14.0], "v1": [6.0, 12.5], "p10": [40.0, 70.0]}),
                      ("stochastic", {"v0": [9.0, 13.0], "v1": [4.0, 15.0], "p10": [45.0, 69.5]})]:
        cert = validate(config(files[name]))
        same = validate({**config(files[name]), "validate": {"epsilon": 0.02, "domain": box}})
        assert cert["domain"] == same["domain"] == ", ".join(f"{k} in [{a:g}, {b:g}]" for k, (a, b) in box.items())
        assert (cert["verdict"], cert["n_run"], cert.counterexample) == (same["verdict"], same["n_run"],
                                                                         same.counterexample)


def test_unmapped_state_variables_keep_sigma(files):
    cert = validate(config(files["deterministic"], {"p10": "Gap"}))
    assert cert["domain"] == "v0 in [0, 20], v1 in [0, 20], p10 in [40, 70]"


def test_an_exported_set_reads_back_as_the_hull_of_its_centres(tmp_path):
    centres = np.random.default_rng(0).uniform([0, 0, 0], [20, 20, 70], (50, 3))
    write_xml(tmp_path / "s.xosc", value_sets(["v0", "v1", "p10"], centres, scenario_file="l.xosc",
                                              description="x", properties={"half_width": 1.0}))
    got = parameter_ranges(tmp_path / "s.xosc")
    assert got == {name: (centres[:, i].min(), centres[:, i].max()) for i, name in enumerate(["v0", "v1", "p10"])}


@pytest.mark.parametrize("case, words", [
    ("not_xml", ["not XML"]),
    ("scenario", ["not an OpenSCENARIO ParameterValueDistribution", "a scenario definition"]),
    ("missing_parameter", ["validate.openscenario.map.p10", "'Headway' is not distributed", "Gap"]),
    ("outside_sigma", ["validate.openscenario.map.p10", "[40, 90]", "outside Sigma", "0 <= low < high <= 70"]),
    ("unknown_state", ["validate.openscenario.map.p99", "unknown state variable"]),
    ("unbounded", ["'Drift'", "without a <Range>"]),
    ("single_value", ["'Cars'", "single value", "low < high"]),
    ("no_file", ["no such file"]),
])
def test_bad_files_and_maps_are_one_line_errors(files, tmp_path, case, words):
    path, mapping = files["deterministic"], dict(MAP)
    if case == "not_xml":
        path = tmp_path / "bad.xosc"
        path.write_text("EgoSpeed = 8..14\n")
    elif case == "scenario":
        path = tmp_path / "scenario.xosc"
        path.write_text(HEADER + "  <CatalogLocations/>\n  <Storyboard/>\n</OpenSCENARIO>\n")
    elif case == "missing_parameter":
        mapping["p10"] = "Headway"
    elif case == "outside_sigma":
        path = tmp_path / "far.xosc"
        path.write_text(DETERMINISTIC.replace('upperLimit="70"', 'upperLimit="90"'))
    elif case == "unknown_state":
        mapping["p99"] = "Gap"
    elif case == "unbounded":
        path, mapping = files["stochastic"], {"v0": "Drift"}
    elif case == "single_value":
        path = tmp_path / "one.xosc"
        path.write_text(STOCHASTIC.replace('<Element value="3" weight="2"/>', ""))
        mapping = {"p10": "Cars"}
    elif case == "no_file":
        path = tmp_path / "nowhere.xosc"
    with pytest.raises(DomainError) as err:
        validate(config(path, mapping))
    text = str(err.value)
    assert "\n" not in text and all(w in text for w in words), text


def test_openscenario_and_a_domain_together_are_refused(files):
    with pytest.raises(ConfigError, match="validate.openscenario: give either"):
        validate(config(files["deterministic"], domain={"v0": [1.0, 2.0]}))


def test_the_cli_validates_from_a_distribution_and_names_a_bad_one_in_one_line(files, tmp_path):
    toml = (f'[scenario]\nname = "lead-follow"\nsv_policy = "idm"\n[validate]\nepsilon = 0.02\n'
            f'[validate.openscenario]\nfile = "{files["deterministic"].name}"\n'
            f'map = {{ v0 = "EgoSpeed", v1 = "LeadSpeed", p10 = "Gap" }}\n')
    (tmp_path / "v.toml").write_text(toml)
    r = subprocess.run([sys.executable, "-m", "farm", "validate", "v.toml", "--json", "--quiet"], cwd=tmp_path,
                       capture_output=True, text=True, timeout=300)
    assert r.returncode in (0, 1), r.stderr
    assert '"domain": "v0 in [8, 14], v1 in [6, 12.5], p10 in [40, 70]"' in r.stdout
    (tmp_path / "w.toml").write_text(toml.replace('"Gap"', '"Headway"'))
    r = subprocess.run([sys.executable, "-m", "farm", "validate", "w.toml"], cwd=tmp_path, capture_output=True,
                       text=True, timeout=300)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "'Headway' is not distributed" in r.stderr, r.stderr
