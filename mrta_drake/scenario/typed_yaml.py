"""Reading YAML files, and typed loading into frozen dataclasses, with errors that name file,
field and value.

``read_yaml`` is the one function that reads a YAML (or JSON) file; it refuses a key given
twice in one mapping, at any depth, naming the line and the key.

``pydrake.common.yaml.yaml_load_typed`` fills dataclasses by assigning fields, which frozen
dataclasses refuse, and its errors name a key but not where it sits. So: ``check_shape``
walks the raw data against the schema first and reports the full field path
(``robots[2].start``), an unknown field or a missing required one (a field without a
default); then Drake's loader fills a mutable twin of the schema, and ``load_typed``
converts the twin into the frozen classes, whose own ``__post_init__`` checks may raise
``InputError`` naming a field relative to themselves. The twin is filled from the data
already parsed (the merge step of ``yaml_load_typed``, which would otherwise take the data
as YAML text and parse it again with PyYAML's pure-Python parser: ~5 % of a warm
quickstart, docs/benchmarks.md, "The first run", "Tenth round").

Fields annotated with a bare ``dict`` hold free-form parameters: they are copied through
untouched and checked later by whoever owns them. A fixed-length ``tuple[T, ...]`` of one
item type is written as a YAML list of that length. A field named after a Python keyword
plus ``_`` (``from_``) is the keyword in YAML (``from``).
"""

import dataclasses
import functools
import keyword
import types
import typing

import yaml
from pydrake.common import yaml as drake_yaml

from mrta_drake.errors import InputError

_MERGE_TAG = "tag:yaml.org,2002:merge"
# libyaml's parser when PyYAML was built with it (the same documents, ~10x faster); errors
# are always reported as the pure-Python parser words them.
_FAST_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
# ``yaml_load_typed``'s defaults: unknown keys refused, fields without YAML keep their
# defaults, a mapping merged into its default's keys.
_DRAKE_OPTIONS = drake_yaml._LoadYamlOptions(allow_yaml_with_no_schema=False,
                                             allow_schema_with_no_yaml=True,
                                             retain_map_defaults=True)


def _short(value) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _join(path: str, key) -> str:
    if isinstance(key, int):
        return f"{path}[{key}]"
    return f"{path}.{key}" if path else str(key)


def yaml_key(f: dataclasses.Field) -> str:
    """The YAML key of dataclass field ``f``: its name, less the ``_`` of ``from_``."""
    name = f.name
    return name[:-1] if name.endswith("_") and keyword.iskeyword(name[:-1]) else name


@functools.cache
def _fields(schema) -> dict[str, tuple[dataclasses.Field, object]]:
    """The init fields of dataclass ``schema`` by YAML key, with their type hints (once per
    schema: the hints are evaluated from the annotations' text; read it, don't change it)."""
    hints = typing.get_type_hints(schema)
    return {yaml_key(f): (f, hints[f.name]) for f in dataclasses.fields(schema) if f.init}


def _required(f: dataclasses.Field) -> bool:
    return f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING


def _optional_inner(tp):
    """T for Optional[T] (T | None), else None."""
    if typing.get_origin(tp) in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        if len(args) == 1 and len(typing.get_args(tp)) == 2:
            return args[0]
    return None


def _tuple_items(schema) -> tuple:
    """The item types of a fixed-length tuple type of one item type, else ()."""
    if typing.get_origin(schema) is not tuple:
        return ()
    items = typing.get_args(schema)
    if not items or Ellipsis in items or len(set(items)) != 1:
        raise TypeError(f"unsupported schema type {schema!r}: use tuple[T, T, ...] of one T")
    return items


def check_shape(value, schema, file: str, path: str = "") -> None:
    """Raise InputError unless raw YAML ``value`` fits type ``schema`` (a dataclass, list[T],
    tuple[T, T, ...], dict[str, T], T | None, float, int, str, bool or bare dict)."""
    inner = _optional_inner(schema)
    if inner is not None:
        if value is not None:
            check_shape(value, inner, file, path)
        return
    origin = typing.get_origin(schema)
    if dataclasses.is_dataclass(schema):
        if not isinstance(value, dict):
            raise InputError(file, path or None, f"expected a mapping, got {_short(value)}")
        fields = _fields(schema)
        for key, item in value.items():
            if key not in fields:
                raise InputError(file, _join(path, key),
                                 f"unknown field (known: {', '.join(sorted(fields))})")
            check_shape(item, fields[key][1], file, _join(path, key))
        for key, (f, _) in fields.items():
            if _required(f) and key not in value:
                raise InputError(file, _join(path, key), "missing")
    elif origin is tuple:
        items = _tuple_items(schema)
        if not isinstance(value, list) or len(value) != len(items):
            noun = "numbers" if items[0] in (int, float) else "values"
            raise InputError(file, path or None,
                             f"expected a list of {len(items)} {noun}, got {_short(value)}")
        for i, item in enumerate(value):
            check_shape(item, items[i], file, _join(path, i))
    elif origin is list or schema is list:
        if not isinstance(value, list):
            raise InputError(file, path or None, f"expected a list, got {_short(value)}")
        if origin is list:
            (item_type,) = typing.get_args(schema)
            for i, item in enumerate(value):
                check_shape(item, item_type, file, _join(path, i))
    elif origin is dict or schema is dict:
        if not isinstance(value, dict):
            raise InputError(file, path or None, f"expected a mapping, got {_short(value)}")
        if origin is dict:
            _, item_type = typing.get_args(schema)
            for key, item in value.items():
                check_shape(item, item_type, file, _join(path, key))
    elif schema is bool:
        if not isinstance(value, bool):
            raise InputError(file, path or None, f"expected true or false, got {_short(value)}")
    elif schema is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise InputError(file, path or None, f"expected an integer, got {_short(value)}")
    elif schema is float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise InputError(file, path or None, f"expected a number, got {_short(value)}")
    elif schema is str:
        if not isinstance(value, str):
            raise InputError(file, path or None, f"expected a string, got {_short(value)}")
    else:
        raise TypeError(f"unsupported schema type {schema!r} at {path}")


@functools.cache
def _thawed(schema):
    """A mutable twin of a (frozen) dataclass type, recursively; tuples become lists, other
    types stay. Bare-dict fields are left out (Drake's loader cannot type them); required
    fields get a placeholder default (``check_shape`` made sure they are given)."""
    inner = _optional_inner(schema)
    if inner is not None:
        return _thawed(inner) | None
    origin = typing.get_origin(schema)
    if origin is list:
        return list[_thawed(typing.get_args(schema)[0])]
    if origin is tuple:
        return list[_thawed(_tuple_items(schema)[0])]
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
        default = {"default": None}
        if f.default is not dataclasses.MISSING:
            default["default"] = f.default
        elif f.default_factory is not dataclasses.MISSING:
            factory = f.default_factory
            default = {"default_factory": lambda factory=factory: _thaw_value(factory())}
        specs.append((f.name, _thawed(hints[f.name]), dataclasses.field(**default)))
    return dataclasses.make_dataclass(f"Mutable{schema.__name__}", specs)


def _thaw_value(value):
    """A frozen default instance as its mutable twin (for default factories)."""
    if dataclasses.is_dataclass(value):
        twin = _thawed(type(value))
        names = {f.name for f in dataclasses.fields(twin)}
        return twin(**{k: _thaw_value(getattr(value, k)) for k in names})
    return value


def _freeze(value, schema, raw, file: str, path: str):
    """Convert a loaded mutable twin ``value`` back to ``schema``; bare-dict fields come
    from ``raw`` (the checked YAML data), or their defaults. A dataclass that refuses its
    values raises InputError naming ``file`` and the field under ``path``."""
    inner = _optional_inner(schema)
    if inner is not None:
        return None if value is None else _freeze(value, inner, raw, file, path)
    origin = typing.get_origin(schema)
    if origin is list:
        (item,) = typing.get_args(schema)
        raw = raw if isinstance(raw, list) else [None] * len(value)
        return [_freeze(v, item, r, file, _join(path, i))
                for i, (v, r) in enumerate(zip(value, raw, strict=True))]
    if origin is tuple:
        item = _tuple_items(schema)[0]
        return tuple(_freeze(v, item, None, file, _join(path, i)) for i, v in enumerate(value))
    if origin is dict:
        _, item = typing.get_args(schema)
        raw = raw if isinstance(raw, dict) else {}
        return {k: _freeze(v, item, raw.get(k), file, _join(path, k)) for k, v in value.items()}
    if not dataclasses.is_dataclass(schema):
        return value
    raw = raw if isinstance(raw, dict) else {}
    kwargs = {}
    for key, (f, hint) in _fields(schema).items():
        if hint is dict:
            if key in raw:
                kwargs[f.name] = dict(raw[key] or {})
            continue
        kwargs[f.name] = _freeze(getattr(value, f.name), hint, raw.get(key), file,
                                 _join(path, key))
    try:
        return schema(**kwargs)
    except InputError as error:  # the dataclass's own __post_init__ checks, field-relative
        raise error.nested(file, path) from None
    except (ValueError, TypeError) as error:
        raise InputError(file, path or None, str(error).splitlines()[0]) from None


def _for_drake(value, schema):
    """``value`` as the twin's data: bare-dict fields removed (Drake's loader cannot type
    them), keys renamed to the fields' Python names (``from`` -> ``from_``)."""
    inner = _optional_inner(schema)
    if inner is not None:
        return None if value is None else _for_drake(value, inner)
    origin = typing.get_origin(schema)
    if origin is list:
        return [_for_drake(v, typing.get_args(schema)[0]) for v in value]
    if origin is tuple:
        return [_for_drake(v, _tuple_items(schema)[0]) for v in value]
    if origin is dict:
        item = typing.get_args(schema)[1]
        return {k: _for_drake(v, item) for k, v in value.items()}
    if not dataclasses.is_dataclass(schema):
        return value
    fields = _fields(schema)
    return {fields[k][0].name: _for_drake(v, fields[k][1]) for k, v in value.items()
            if fields[k][1] is not dict}


def load_typed(data, schema, file: str, path: str = ""):
    """Build a frozen ``schema`` instance from raw YAML ``data`` (already parsed), raising
    InputError that names ``file`` and the field path on any mismatch."""
    if typing.get_origin(schema) is list:  # Drake's loader wants a mapping at the root
        check_shape(data, schema, file, path)
        (item,) = typing.get_args(schema)
        return [load_typed(v, item, file, _join(path, i)) for i, v in enumerate(data)]
    data = {} if data is None else data
    check_shape(data, schema, file, path)
    twin = _thawed(schema)
    mutable = twin()
    try:  # ``yaml_load_typed`` less its parsing of YAML text (the data is parsed already)
        drake_yaml._merge_yaml_dict_into_target(options=_DRAKE_OPTIONS,
                                                yaml_dict=_for_drake(data, schema),
                                                target=mutable, target_schema=twin)
    except Exception as error:  # Drake names the key only; check_shape caught the usual cases.
        raise InputError(file, path or None, str(error).splitlines()[0]) from None
    return _freeze(mutable, schema, data, file, path)


def read_yaml(path: str, what: str = "file"):
    """The content of the YAML (or JSON) file ``path``. A missing, unreadable or empty file,
    a syntax error or a key given twice in one mapping raises InputError, naming the line;
    ``what`` names the file in the message (``"scenario file"``)."""
    try:
        with open(path, encoding="utf-8") as f:
            text = f.read()
    except FileNotFoundError:
        raise InputError(path, None, f"{what} not found") from None
    except IsADirectoryError:
        raise InputError(path, None, f"{what} is a directory") from None
    except UnicodeDecodeError:
        raise InputError(path, None, f"{what} is not UTF-8 text") from None
    try:
        return _parse(text, _FAST_LOADER, path, what)
    except yaml.YAMLError:
        pass
    try:
        return _parse(text, yaml.SafeLoader, path, what)
    except yaml.YAMLError as error:
        mark = getattr(error, "problem_mark", None) or getattr(error, "context_mark", None)
        where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark else ""
        said = [getattr(error, "context", None), getattr(error, "problem", None)]
        problem = ", ".join(part for part in said if part) or str(error).splitlines()[0]
        raise InputError(path, None, f"YAML syntax error at {where}{problem}") from None


def _parse(text: str, loader_class, path: str, what: str):
    """The content of the YAML ``text`` of file ``path`` parsed by ``loader_class`` (see
    ``read_yaml``); a syntax error raises the loader's ``yaml.YAMLError``."""
    loader = loader_class(text)
    try:
        node = loader.get_single_node()
        if node is None:
            raise InputError(path, None, f"{what} is empty")
        _check_unique_keys(loader, node, path, "", set())
        return loader.construct_document(node)
    finally:
        loader.dispose()


def _check_unique_keys(loader: yaml.SafeLoader, node: yaml.Node, file: str, path: str,
                       visited: set[int]) -> None:
    """Raise InputError at the first mapping under ``node`` that gives a key twice (keys
    compared as the values they load as: ``1`` and ``1.0`` are one key, ``"1"`` another)."""
    if id(node) in visited:  # an alias of a node already checked
        return
    visited.add(id(node))
    if isinstance(node, yaml.SequenceNode):
        for i, item in enumerate(node.value):
            _check_unique_keys(loader, item, file, _join(path, i), visited)
    elif isinstance(node, yaml.MappingNode):
        lines = {}
        for key_node, value_node in node.value:
            here = path
            if isinstance(key_node, yaml.ScalarNode) and key_node.tag != _MERGE_TAG:
                key = loader.construct_object(key_node)
                here = _join(path, key)
                line = key_node.start_mark.line + 1
                if key in lines:
                    raise InputError(file, here, f"duplicate key {key!r} at line {line} "
                                     f"(first given at line {lines[key]})")
                lines[key] = line
            _check_unique_keys(loader, value_node, file, here, visited)
