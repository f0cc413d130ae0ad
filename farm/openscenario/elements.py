"""The XML both formats are written in: elements from keyword attributes, numbers as
text, and the atomic write every file of this package goes through."""

from __future__ import annotations

import datetime as _dt
import xml.etree.ElementTree as ET
from pathlib import Path

from farm.directory.files import atomic_write
from scenarios.version import __version__

AUTHOR = f"scenario-farm {__version__}"


def num(x: float) -> str:
    """A number as XML text: the shortest repr that reads back as the same double."""
    x = float(x)
    return repr(0.0 if x == 0 else x)  # no "-0.0"


def el(parent: ET.Element | None, tag: str, **attrs) -> ET.Element:
    """A child of ``parent`` (or a root) with ``attrs`` as text: numbers via ``num``,
    booleans as "true" / "false"; a trailing underscore in a name is dropped (``class_``)."""
    text = {}
    for key, value in attrs.items():
        if isinstance(value, bool):
            value = "true" if value else "false"
        elif isinstance(value, (int, float)) and not isinstance(value, bool):
            value = str(value) if isinstance(value, int) else num(value)
        text[key.rstrip("_")] = str(value)
    return ET.Element(tag, text) if parent is None else ET.SubElement(parent, tag, text)


def now() -> str:
    """The file header's date (xsd:dateTime, UTC, whole seconds)."""
    return _dt.datetime.now(_dt.timezone.utc).replace(microsecond=0, tzinfo=None).isoformat()


def write_xml(path: Path, root: ET.Element) -> Path:
    ET.indent(root, space="  ")
    data = ET.tostring(root, encoding="utf-8", xml_declaration=True) + b"\n"
    atomic_write(Path(path), lambda fh: fh.write(data))
    return Path(path)
