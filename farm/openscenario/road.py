"""The straight road the exported scenarios drive on, as ASAM OpenDRIVE 1.5.

One road (id 1) along the x axis from x = 0, flat (an explicit zero elevation, not an
empty ``elevationProfile``, which the 1.5 schema rejects), with one driving lane to the
right of the reference line (lane -1, right-hand traffic): a position s on the road is
x = s, y = -LANE_WIDTH / 2 on the lane's centre line.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

from farm.openscenario.elements import el, now, write_xml

ROAD_ID = "1"
LANE_ID = -1
LANE_WIDTH = 3.5  # [m]


def road_xml(length: float) -> ET.Element:
    root = el(None, "OpenDRIVE")
    el(root, "header", revMajor=1, revMinor=5, name="scenario-farm straight road", version="1.00", date=now(),
       north=LANE_WIDTH, south=-LANE_WIDTH, east=float(length), west=0.0, vendor="scenario-farm")
    road = el(root, "road", name="straight", length=float(length), id=ROAD_ID, junction="-1", rule="RHT")
    el(road, "type", s=0.0, type="motorway")
    geometry = el(el(road, "planView"), "geometry", s=0.0, x=0.0, y=0.0, hdg=0.0, length=float(length))
    el(geometry, "line")
    el(el(road, "elevationProfile"), "elevation", s=0.0, a=0.0, b=0.0, c=0.0, d=0.0)
    section = el(el(road, "lanes"), "laneSection", s=0.0)
    centre = el(el(section, "center"), "lane", id=0, type="none", level=False)
    el(centre, "roadMark", sOffset=0.0, type="solid", weight="standard", color="standard", width=0.12)
    lane = el(el(section, "right"), "lane", id=LANE_ID, type="driving", level=False)
    el(lane, "width", sOffset=0.0, a=LANE_WIDTH, b=0.0, c=0.0, d=0.0)
    el(lane, "roadMark", sOffset=0.0, type="solid", weight="standard", color="standard", width=0.12)
    return root


def write_road(path: Path, length: float) -> Path:
    return write_xml(path, road_xml(length))
