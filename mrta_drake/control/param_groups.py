"""The controllers' parameters come in groups (frozen dataclasses, one per job, checked in
``__post_init__`` with ``errors.require_*``). Here: the table of where the fields of the old
flat layout moved to.

A params class may list its old field names in a class attribute ``moved_fields`` (old name ->
new dotted place); ``stack.blocks.resolve_block`` then answers an old key with its new place.
"""

import dataclasses


def moved_from_flat(groups: dict[str, type], renamed: dict[str, str]) -> dict[str, str]:
    """Where each field of a flat layout went: a field of group class ``groups[name]`` to
    ``name.field``, and each old name of ``renamed`` to its new dotted place."""
    moved = {f.name: f"{name}.{f.name}" for name, group in groups.items()
             for f in dataclasses.fields(group)}
    return moved | renamed
