"""A second version of the controller under test, as a team would ship it: lead-follow
whose SV runs the IDM with a gentler braking limit (-4.5 m/s^2 instead of -4.67: tuned for
comfort). Compare it with the campaign's controller on the very same runs:

    scenario-farm estimate runs/lead-follow-idm --versus-scenario lead_follow_v2:LeadFollowV2

(run from this directory, or with it on PYTHONPATH: the class is imported from the working
directory, by the CLI and by Ray workers). The paired difference of the two failure rates
is far narrower than two separate intervals (docs/estimate.md).
"""

from dataclasses import replace

from scenarios.lead_follow import LeadFollow
from scenarios.policies import SV_IDM, idm_accel

MIN_ACCEL_V2 = -4.5  # [m/s^2]
IDM_V2 = replace(SV_IDM, min_accel=MIN_ACCEL_V2)


def idm_v2(v0, v1, gap):
    """The SV's IDM, braking at most 4.5 m/s^2."""
    return idm_accel(v0, v1, gap, IDM_V2)


class LeadFollowV2(LeadFollow):
    name = "lead-follow-v2"
    sv_policies = {"idm": idm_v2}  # the same policy name, a new version of it
