"""The road network and route file of the SUMO back end, written by the package.

One straight single-lane road per run slot ("r<i>", lane "r<i>_0"), the roads side by
side 10 m apart and unconnected, so a batch of B runs is one simulation whose one
``simulationStep`` advances every run while no run can see another: SUMO's car
following and collision checks only look along a vehicle's own lane. Single-lane
edges also skip all lane-change computations (a multi-lane edge would evaluate the
lane-change model of every vehicle each step, even with changes disabled).

The .net.xml is written directly instead of by netconvert: the pip wheels (libsumo,
sumo-data) ship no netconvert binary, and for parallel straight lanes the format is
trivial (edges with one lane and its shape, dead-end junctions at both ends).
"""

from __future__ import annotations

from xml.sax.saxutils import quoteattr

LANE_SPACING = 10.0  # [m] lateral distance between the roads (cosmetic: roads never interact)
LANE_SPEED = 100.0  # [m/s] speed limit, far above every Sigma, so it never binds
VEHICLE_LENGTH = 5.0  # [m] every vehicle; fleet3's front-to-front state assumes 5 m

# The commanded vehicles (lead, follower): with speed mode 0 their speed is whatever
# setSpeed says; these limits only matter before the first command.
COMMANDED_VTYPE = {
    "length": VEHICLE_LENGTH, "minGap": 0.0, "maxSpeed": 1000.0, "accel": 1000.0, "decel": 1000.0,
    "emergencyDecel": 1000.0, "sigma": 0.0, "speedFactor": 1.0, "speedDev": 0.0, "tau": 1.0,
}
COMMANDED_VTYPE_ID = "commanded"


def lane_id(slot: int) -> str:
    return f"r{slot}_0"


def route_id(slot: int) -> str:
    return f"q{slot}"


def write_net(path: str, slots: int, length: float) -> None:
    """``slots`` parallel single-lane roads of ``length`` metres."""
    width = LANE_SPACING * max(slots - 1, 0)
    lines = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        '<net version="1.20" junctionCornerDetail="5" limitTurnSpeed="5.50">',
        f'  <location netOffset="0.00,0.00" convBoundary="0.00,0.00,{length:.2f},{width:.2f}" '
        f'origBoundary="0.00,0.00,{length:.2f},{width:.2f}" projParameter="!"/>',
    ]
    for i in range(slots):
        y = i * LANE_SPACING
        lines.append(f'  <edge id="r{i}" from="a{i}" to="b{i}" priority="1">')
        lines.append(f'    <lane id="r{i}_0" index="0" speed="{LANE_SPEED:.2f}" length="{length:.2f}" '
                     f'shape="0.00,{y:.2f} {length:.2f},{y:.2f}"/>')
        lines.append("  </edge>")
    for i in range(slots):
        y = i * LANE_SPACING
        lines.append(f'  <junction id="a{i}" type="dead_end" x="0.00" y="{y:.2f}" incLanes="" intLanes="" '
                     f'shape="0.00,{y + 1.6:.2f} 0.00,{y - 1.6:.2f}"/>')
        lines.append(f'  <junction id="b{i}" type="dead_end" x="{length:.2f}" y="{y:.2f}" incLanes="r{i}_0" '
                     f'intLanes="" shape="{length:.2f},{y - 1.6:.2f} {length:.2f},{y + 1.6:.2f}"/>')
    lines.append("</net>")
    with open(path, "w") as fh:
        fh.write("\n".join(lines) + "\n")


def write_routes(path: str, slots: int, vtypes: dict[str, dict[str, str]]) -> None:
    """One route per slot and the vTypes: the commanded one and each SV type in use."""
    lines = ['<?xml version="1.0" encoding="UTF-8"?>', "<routes>"]
    for vid, attrs in {COMMANDED_VTYPE_ID: _text(COMMANDED_VTYPE), **vtypes}.items():
        attrs = {**attrs, "length": repr(VEHICLE_LENGTH)}
        body = " ".join(f"{k}={quoteattr(v)}" for k, v in attrs.items())
        lines.append(f"  <vType id={quoteattr(vid)} {body}/>")
    for i in range(slots):
        lines.append(f'  <route id="{route_id(i)}" edges="r{i}"/>')
    lines.append("</routes>")
    with open(path, "w") as fh:
        fh.write("\n".join(lines) + "\n")


def _text(attrs: dict) -> dict[str, str]:
    return {k: repr(float(v)) for k, v in attrs.items()}
