"""The controllers' parameters come in groups (frozen dataclasses, one per job). Here: the
checks the groups run in ``__post_init__``, each raising an ``InputError`` naming the field and
its value (the scenario loader adds the file and where the group sits), and the table of
where the fields of the old flat layout moved to.

A params class may list its old field names in a class attribute ``moved_fields`` (old name ->
new dotted place); ``stack.blocks.resolve_block`` then answers an old key with its new place.
"""

import dataclasses

from mrta_drake.errors import InputError


def require_positive(params, *names: str) -> None:
    """Every field ``names`` of ``params`` > 0."""
    for name in names:
        value = getattr(params, name)
        if not value > 0:
            raise InputError(None, name, f"must be > 0, got {value!r}")


def require_non_negative(params, *names: str) -> None:
    """Every field ``names`` of ``params`` >= 0."""
    for name in names:
        value = getattr(params, name)
        if not value >= 0:
            raise InputError(None, name, f"must be >= 0, got {value!r}")


def require_choice(params, name: str, choices) -> None:
    """Field ``name`` of ``params`` one of ``choices``."""
    value = getattr(params, name)
    if value not in choices:
        raise InputError(None, name, f"must be one of {', '.join(choices)}, got {value!r}")


def moved_from_flat(groups: dict[str, type], renamed: dict[str, str]) -> dict[str, str]:
    """Where each field of a flat layout went: a field of group class ``groups[name]`` to
    ``name.field``, and each old name of ``renamed`` to its new dotted place."""
    moved = {f.name: f"{name}.{f.name}" for name, group in groups.items()
             for f in dataclasses.fields(group)}
    return moved | renamed
