"""ASAM OpenSCENARIO / OpenDRIVE out and in (docs/openscenario.md).

Out: ``export.export_openscenario(DIR)`` writes a campaign's failing runs as concrete
scenarios on a straight road and its certified set as a parameter distribution. In:
``ranges.claimed_box`` reads a logical scenario's parameter ranges as the claimed domain
of ``validate`` (``[validate.openscenario]``).
"""
