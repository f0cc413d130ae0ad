"""A frozen dataclass as a JSON file of a public interface (summary.json,
certificate.json): its fields are the file's keys, in order.

Reading is lenient where files age and strict where they lie: a key the dataclass does
not know (an older or newer writer's) is kept in ``extra`` and written back; a key an
older writer did not write takes the field's default; a required key that is missing,
or a value of the wrong JSON type, is a one-line ``CampaignError`` naming the key.
"""

from __future__ import annotations

import dataclasses
import typing
from pathlib import Path
from typing import ClassVar

from farm.directory.files import read_json, write_json
from scenarios.errors import CampaignError

_JSON_TYPES = {bool: (bool,), int: (int,), float: (int, float), str: (str,), list: (list,), dict: (dict,)}


def record_to_json(record, leave_out: tuple[str, ...] = (), omit_none: tuple[str, ...] = ()) -> dict:
    """The fields as JSON keys, in declaration order, then ``extra``'s keys; fields
    named in ``leave_out`` are left out, those in ``omit_none`` when None."""
    out = {}
    for f in dataclasses.fields(record):
        value = getattr(record, f.name)
        if f.name in ("extra", *leave_out) or (f.name in omit_none and value is None):
            continue
        out[f.name] = value
    if "extra" not in leave_out:
        out.update(getattr(record, "extra", {}))
    return out


def record_from_json(cls, data, source: str, required: tuple[str, ...], **known):
    """An instance of the dataclass ``cls`` from the JSON object ``data`` (read from
    ``source``, for messages); ``known``: fields already taken from ``data``. Keys
    that name no field go to the ``extra`` field (a class without one takes none)."""
    if not isinstance(data, dict):
        raise CampaignError(f"{source}: expected a JSON object, got {type(data).__name__}")
    missing = [k for k in required if k not in data]
    if missing:
        raise CampaignError(f"{source}: lacks {', '.join(missing)}")
    hints = typing.get_type_hints(cls)
    fields = {f.name for f in dataclasses.fields(cls)}
    keeps_extra = "extra" in fields
    fields -= {"extra", *known}
    values, extra = dict(known), {}
    for key, value in data.items():
        if key not in fields:
            if not keeps_extra:
                raise CampaignError(f"{source}: unknown key {key}")
            extra[key] = value
            continue
        allowed = _allowed(hints[key])
        if not (value is None and _optional(hints[key])) and \
                (not isinstance(value, allowed) or (isinstance(value, bool) and bool not in allowed)):
            raise CampaignError(f"{source}: {key} is {value!r}; expected {' or '.join(t.__name__ for t in allowed)}")
        values[key] = value
    return cls(**values, extra=extra) if keeps_extra else cls(**values)


def _optional(hint) -> bool:
    return type(None) in typing.get_args(hint)


def _allowed(hint) -> tuple[type, ...]:
    """The JSON value types a field of type ``hint`` accepts."""
    options = [a for a in typing.get_args(hint) if a is not type(None)] if _optional(hint) else [hint]
    allowed = [t for option in options for t in _JSON_TYPES.get(typing.get_origin(option) or option, (object,))]
    return tuple(dict.fromkeys(allowed))


class JsonFile:
    """A record stored as ``FILE`` in a directory: ``read``, ``write``, and the value of a
    JSON key by ``record[key]`` (for code written against the JSON)."""

    FILE: ClassVar[str]
    MISSING: ClassVar[str]  # the message when there is no file ({directory}, {file})

    def to_json(self) -> dict:
        raise NotImplementedError

    @classmethod
    def from_json(cls, data, source: str):
        raise NotImplementedError

    @classmethod
    def read(cls, directory):
        """The record in ``directory``; a one-line CampaignError when the file is absent,
        unreadable or not such a record."""
        path = Path(directory) / cls.FILE
        return cls.from_json(read_json(path, missing=cls.MISSING.format(directory=directory, file=cls.FILE)), str(path))

    def write(self, directory) -> Path:
        path = Path(directory) / self.FILE
        write_json(path, self.to_json())
        return path

    def __getitem__(self, key: str):
        return self.to_json()[key]

