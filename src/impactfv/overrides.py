"""``--set KEY=VALUE``: change one key of a case on the command line.

KEY is the key path the error messages use (``run.end_time``, ``body[0].velocity``,
``body[1].mesh.scale``, ``contact[0].wall.point``); VALUE is a TOML value (``3e-4``,
``[10, 0]``, ``"fem-t3"``, ``{ x = 0.0 }``); a bare word that is no TOML value is taken as a
string (``run.method=fem-t3``). Keys are checked against the schema before the case is
validated, with the same one-line error and nearest-key suggestion as a key in the file; the
value is then validated with the rest of the case.
"""

from __future__ import annotations

import copy
import difflib
import re
import tomllib
from typing import get_args, get_origin

from pydantic import BaseModel

from .errors import InputError

_PART = re.compile(r"([A-Za-z_][A-Za-z0-9_]*)((?:\[\d+\])*)$")


def parse_key(key: str, where: str) -> list:
    """``body[0].mesh.scale`` -> ["body", 0, "mesh", "scale"]."""
    out = []
    for part in key.split("."):
        m = _PART.match(part.strip())
        if not m:
            raise InputError(f"{where}: expected a key path like run.end_time or "
                             f"body[0].velocity, got {key!r}")
        out.append(m.group(1))
        out += [int(i) for i in re.findall(r"\[(\d+)\]", m.group(2))]
    return out


def parse_value(text: str):
    """A TOML value, or the text itself when it is a bare word and no TOML value."""
    try:
        return tomllib.loads(f"value = {text}")["value"]
    except RecursionError:
        raise InputError(f"not a TOML value: {text[:20]!r}... (arrays or tables nested too "
                         "deeply)") from None
    except tomllib.TOMLDecodeError:
        if re.fullmatch(r"[A-Za-z0-9_.+\-]+", text.strip()):
            return text.strip()
        raise InputError(f"not a TOML value: {text!r} (quote strings, e.g. '\"text\"', "
                         "write lists as [1.0, 2.0] and tables as { x = 0.0 })") from None


def _model_of(annotation):
    """The pydantic model an annotation holds (directly, in a list or Optional), or None."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    for arg in get_args(annotation) if get_origin(annotation) is not None else ():
        found = _model_of(arg)
        if found is not None:
            return found
    return None


def _is_list(annotation) -> bool:
    origin = get_origin(annotation)
    if origin is list:
        return True
    return any(_is_list(a) for a in get_args(annotation)) if origin is not None else False


def _shown(path) -> str:
    out = ""
    for part in path:
        out += f"[{part}]" if isinstance(part, int) else ("." if out else "") + str(part)
    return out


def apply(data: dict, overrides, root: type, source: str) -> tuple[dict, set]:
    """A copy of the case ``data`` with each ``KEY=VALUE`` of ``overrides`` set, and the set
    of key paths set (as error messages show them). ``root`` is the schema's top model."""
    data = copy.deepcopy(data)
    paths = set()
    for text in overrides or ():
        key, sep, value_text = text.partition("=")
        if not sep or not key.strip():
            raise InputError(f"{source}: --set {text!r}: expected KEY=VALUE, e.g. "
                             "run.end_time=3e-4")
        where = f"{source}: --set {key.strip()}"
        path = parse_key(key.strip(), where)
        try:
            value = parse_value(value_text)
        except InputError as exc:
            raise InputError(f"{where}: {exc}") from None
        node, model = data, root
        for depth, part in enumerate(path):
            last = depth == len(path) - 1
            shown = _shown(path[:depth + 1])
            if isinstance(part, int):
                if not isinstance(node, list):
                    raise InputError(f"{where}: {_shown(path[:depth])} is not a list")
                if part >= len(node):
                    n = len(node)
                    have = f"indices 0 to {n - 1}" if n else "none"
                    raise InputError(f"{where}: the case has {n} "
                                     f"{'entry' if n == 1 else 'entries'} in "
                                     f"{_shown(path[:depth])} ({have}); --set changes "
                                     "entries, it adds none")
                if last:
                    node[part] = value
                else:
                    node = node[part]
                continue
            if model is None:
                raise InputError(f"{where}: {_shown(path[:depth])} takes a value, not keys")
            if part not in model.model_fields:
                close = difflib.get_close_matches(part, list(model.model_fields), n=1)
                hint = f"did you mean {close[0]!r}?" if close else \
                    f"expected one of: {', '.join(model.model_fields)}"
                raise InputError(f"{source}: --set {shown}: unknown key ({hint})")
            if not isinstance(node, dict):
                raise InputError(f"{where}: {_shown(path[:depth]) or 'the case'} is not a "
                                 "table")
            annotation = model.model_fields[part].annotation
            if last:
                node[part] = value
                break
            nxt = path[depth + 1]
            if isinstance(nxt, int):
                if not _is_list(annotation) and not isinstance(node.get(part), list):
                    raise InputError(f"{where}: {shown} is not a list")
                node = node.setdefault(part, [])
                model = _model_of(annotation)
            else:
                node = node.setdefault(part, {})
                model = _model_of(annotation)
        paths.add(_shown(path))
    return data, paths
