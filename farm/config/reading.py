"""Reading a config: from a TOML file or string, a dict or a Config; and writing one back
as TOML (a campaign started from Python has no file)."""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

from farm.config.model import MAX_DEPTH, Config, normalize
from scenarios.errors import ConfigError

MAX_CHARS = 4 * 2**20  # the largest configs (sets of constraints) are kilobytes


def load(source, overrides: dict | None = None) -> Config:
    """A config from a TOML file (str or Path), a TOML string, a dict or a Config."""
    if isinstance(source, Config):
        cfg = source
    elif isinstance(source, dict):
        cfg = normalize(source)
    elif isinstance(source, Path) or (isinstance(source, str) and "\n" not in source and "=" not in source):
        cfg = parse(read_text(source), str(source))
    else:
        cfg = parse(str(source))
    return cfg.with_overrides(overrides) if overrides else cfg


def read_text(path) -> str:
    """A config file's text, read once (it may be a stream: ``quantify <(cat c.toml)``),
    without a UTF-8 byte-order mark. Raises ConfigError (one line)."""
    path = Path(path)
    try:
        with open(path, encoding="utf-8-sig") as fh:  # -sig: a byte-order mark is no TOML
            text = fh.read(MAX_CHARS + 1)  # bounded: /dev/zero or /dev/urandom must not fill the memory
    except FileNotFoundError:
        raise ConfigError(f"{path}: no such config file") from None
    except IsADirectoryError:
        raise ConfigError(f"{path}: is a directory, not a config file") from None
    except UnicodeDecodeError as exc:
        raise ConfigError(f"{path}: not UTF-8 text (byte {exc.start}: {exc.reason}); a config is a UTF-8 TOML "
                          f"file") from None
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read the config ({exc.strerror or type(exc).__name__})") from None
    if len(text) > MAX_CHARS:
        raise ConfigError(f"{path}: larger than a config may be; allowed at most {MAX_CHARS // 2**20} MiB of "
                          f"TOML text")
    return text


def parse(text: str, where: str = "config") -> Config:
    """A checked config from TOML text; ``where`` names it in errors (the file)."""
    return normalize(parse_tables(text, where), where=where)


def parse_tables(text: str, where: str = "config") -> dict:
    """TOML text as tables, unchecked (a part of a config: an estimate's [estimate])."""
    text = text.removeprefix("\ufeff")
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{where}: not valid TOML ({exc})") from None
    except RecursionError:
        raise ConfigError(f"{where}: nested too deeply to read; allowed at most {MAX_DEPTH} levels") from None


def to_toml(cfg: Config) -> str:
    """The normalized config as TOML (a campaign started from Python has no file)."""
    lines = []
    for section, values in cfg.model_dump(mode="json", exclude_none=True).items():
        lines.append(f"[{section}]")
        lines += [f"{k} = {_toml_value(v)}" for k, v in values.items()]
        lines.append("")
    return "\n".join(lines)


def _toml_value(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value)  # a TOML basic string
    if isinstance(value, list):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{json.dumps(k)} = {_toml_value(v)}" for k, v in value.items()) + " }"
    raise TypeError(f"no TOML form for {value!r}")
