"""Typed YAML loading into frozen dataclasses, with errors that name file, field and value.

``pydrake.common.yaml.yaml_load_typed`` fills dataclasses by assigning fields, which frozen
dataclasses refuse, and its errors name a key but not where it sits. So: ``check_shape``
walks the raw data against the schema first and reports the full field path
(``robots[2].start``); then ``yaml_load_typed`` builds a mutable twin of the schema, and
``load_typed`` converts the twin into the frozen classes.

Fields annotated with a bare ``dict`` hold free-form parameters: they are copied through
untouched and checked later by whoever owns them.
"""

import dataclasses
import functools
import types
import typing

import yaml
from pydrake.common.yaml import yaml_load_typed

from mrta_drake.errors import InputError


def _short(value) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _join(path: str, key) -> str:
    if isinstance(key, int):
        return f"{path}[{key}]"
    return f"{path}.{key}" if path else str(key)


def _optional_inner(tp):
    """T for Optional[T] (T | None), else None."""
    if typing.get_origin(tp) in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        if len(args) == 1 and len(typing.get_args(tp)) == 2:
            return args[0]
    return None


def check_shape(value, schema, file: str, path: str = "") -> None:
    """Raise InputError unless raw YAML ``value`` fits type ``schema`` (a dataclass, list[T],
    dict[str, T], T | None, float, int, str, bool or bare dict)."""
    inner = _optional_inner(schema)
    if inner is not None:
        if value is not None:
            check_shape(value, inner, file, path)
        return
    origin = typing.get_origin(schema)
    if dataclasses.is_dataclass(schema):
        if not isinstance(value, dict):
            raise InputError(file, path or None, f"expected a mapping, got {_short(value)}")
        hints = typing.get_type_hints(schema)
        known = {f.name for f in dataclasses.fields(schema) if f.init}
        for key, item in value.items():
            if key not in known:
                raise InputError(file, _join(path, key),
                                 f"unknown field (known: {', '.join(sorted(known))})")
            check_shape(item, hints[key], file, _join(path, key))
    elif origin is list or schema is list:
        if not isinstance(value, list):
            raise InputError(file, path, f"expected a list, got {_short(value)}")
        if origin is list:
            (item_type,) = typing.get_args(schema)
            for i, item in enumerate(value):
                check_shape(item, item_type, file, _join(path, i))
    elif origin is dict or schema is dict:
        if not isinstance(value, dict):
            raise InputError(file, path, f"expected a mapping, got {_short(value)}")
        if origin is dict:
            _, item_type = typing.get_args(schema)
            for key, item in value.items():
                check_shape(item, item_type, file, _join(path, key))
    elif schema is bool:
        if not isinstance(value, bool):
            raise InputError(file, path, f"expected true or false, got {_short(value)}")
    elif schema is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise InputError(file, path, f"expected an integer, got {_short(value)}")
    elif schema is float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise InputError(file, path, f"expected a number, got {_short(value)}")
    elif schema is str:
        if not isinstance(value, str):
            raise InputError(file, path, f"expected a string, got {_short(value)}")
    else:
        raise TypeError(f"unsupported schema type {schema!r} at {path}")


@functools.cache
def _thawed(schema):
    """A mutable twin of a (frozen) dataclass type, recursively; other types unchanged.
    Bare-dict fields are left out (yaml_load_typed cannot type them)."""
    inner = _optional_inner(schema)
    if inner is not None:
        return _thawed(inner) | None
    origin = typing.get_origin(schema)
    if origin is list:
        return list[_thawed(typing.get_args(schema)[0])]
    if origin is dict:
        key, item = typing.get_args(schema)
        return dict[key, _thawed(item)]
    if not dataclasses.is_dataclass(schema):
        return schema
    hints = typing.get_type_hints(schema)
    specs = []
    for f in dataclasses.fields(schema):
        if hints[f.name] is dict:
            continue
        default = {}
        if f.default is not dataclasses.MISSING:
            default["default"] = f.default
        elif f.default_factory is not dataclasses.MISSING:
            factory = f.default_factory
            default["default_factory"] = (
                lambda factory=factory: _thaw_value(factory()))
        specs.append((f.name, _thawed(hints[f.name]), dataclasses.field(**default)))
    return dataclasses.make_dataclass(f"Mutable{schema.__name__}", specs)


def _thaw_value(value):
    """A frozen default instance as its mutable twin (for default factories)."""
    if dataclasses.is_dataclass(value):
        twin = _thawed(type(value))
        names = {f.name for f in dataclasses.fields(twin)}
        return twin(**{k: _thaw_value(getattr(value, k)) for k in names})
    return value


def _freeze(value, schema, raw):
    """Convert a loaded mutable twin ``value`` back to ``schema``; bare-dict fields come
    from ``raw`` (the checked YAML data), or their defaults."""
    inner = _optional_inner(schema)
    if inner is not None:
        return None if value is None else _freeze(value, inner, raw)
    origin = typing.get_origin(schema)
    if origin is list:
        (item,) = typing.get_args(schema)
        raw = raw if isinstance(raw, list) else [None] * len(value)
        return [_freeze(v, item, r) for v, r in zip(value, raw, strict=True)]
    if origin is dict:
        _, item = typing.get_args(schema)
        raw = raw if isinstance(raw, dict) else {}
        return {k: _freeze(v, item, raw.get(k)) for k, v in value.items()}
    if not dataclasses.is_dataclass(schema):
        return value
    hints = typing.get_type_hints(schema)
    raw = raw if isinstance(raw, dict) else {}
    kwargs = {}
    for f in dataclasses.fields(schema):
        if hints[f.name] is dict:
            if f.name in raw:
                kwargs[f.name] = dict(raw[f.name] or {})
            continue
        kwargs[f.name] = _freeze(getattr(value, f.name), hints[f.name], raw.get(f.name))
    return schema(**kwargs)


def _without_bare_dicts(value, schema):
    """``value`` with the bare-dict fields removed, so yaml_load_typed accepts it."""
    inner = _optional_inner(schema)
    if inner is not None:
        return None if value is None else _without_bare_dicts(value, inner)
    origin = typing.get_origin(schema)
    if origin is list:
        return [_without_bare_dicts(v, typing.get_args(schema)[0]) for v in value]
    if origin is dict:
        item = typing.get_args(schema)[1]
        return {k: _without_bare_dicts(v, item) for k, v in value.items()}
    if not dataclasses.is_dataclass(schema):
        return value
    hints = typing.get_type_hints(schema)
    return {k: _without_bare_dicts(v, hints[k]) for k, v in value.items() if hints[k] is not dict}


def load_typed(data, schema, file: str, path: str = ""):
    """Build a frozen ``schema`` instance from raw YAML ``data`` (already parsed), raising
    InputError that names ``file`` and the field path on any mismatch."""
    if typing.get_origin(schema) is list:  # yaml_load_typed wants a mapping at the root
        check_shape(data, schema, file, path)
        (item,) = typing.get_args(schema)
        return [load_typed(v, item, file, _join(path, i)) for i, v in enumerate(data)]
    data = {} if data is None else data
    check_shape(data, schema, file, path)
    text = yaml.safe_dump(_without_bare_dicts(data, schema), sort_keys=False)
    try:
        mutable = yaml_load_typed(schema=_thawed(schema), data=text)
    except Exception as error:  # Drake names the key only; check_shape caught the usual cases.
        raise InputError(file, path or None, str(error).splitlines()[0]) from None
    try:
        return _freeze(mutable, schema, data)
    except (ValueError, TypeError) as error:  # a dataclass's own __post_init__ checks
        raise InputError(file, path or None, str(error).splitlines()[0]) from None


def read_yaml(path: str, what: str = "file"):
    """Parse a YAML (or JSON) file, raising InputError for a missing file or a syntax
    error, naming the line."""
    try:
        with open(path, encoding="utf-8") as f:
            return yaml.safe_load(f)
    except FileNotFoundError:
        raise InputError(path, None, f"{what} not found") from None
    except IsADirectoryError:
        raise InputError(path, None, f"{what} is a directory") from None
    except yaml.YAMLError as error:
        mark = getattr(error, "problem_mark", None)
        where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark else ""
        problem = getattr(error, "problem", None) or str(error).splitlines()[0]
        raise InputError(path, None, f"YAML syntax error at {where}{problem}") from None
