"""The one error type for bad user input (scenario YAML, task files, maps, CLI flags), and the
checks self-checking params dataclasses run in ``__post_init__``."""

import math
import numbers


class InputError(ValueError):
    """Bad user input; the message is one line naming the file, the field and the value.

    The CLI prints ``str(error)`` and exits with status 2; it never shows a traceback.
    """

    def __init__(self, file: str | None, field: str | None, message: str):
        self.file = file
        self.field = field
        self.message = message
        where = ": ".join(part for part in (str(file) if file else None, field) if part)
        super().__init__(f"{where}: {message}" if where else message)

    def nested(self, file: str | None, path: str | None) -> "InputError":
        """This error for a value found at field ``path`` of ``file``: its own field, if
        any, is taken relative to ``path`` (``walls[3]`` + ``doors[0].width``)."""
        if not self.field:
            field = path or None
        elif not path:
            field = self.field
        else:
            field = path + ("" if self.field.startswith("[") else ".") + self.field
        return InputError(file or self.file, field, self.message)


def require_positive(params, *names: str, unit: str = "") -> None:
    """Every field ``names`` of ``params`` a finite number > 0 (``unit``, e.g. " m", follows
    the bound)."""
    for name in names:
        _require_number(name, getattr(params, name), "> 0", unit, lambda value: value > 0)


def require_non_negative(params, *names: str, unit: str = "") -> None:
    """Every field ``names`` of ``params`` a finite number >= 0 (``unit``, e.g. " m", follows
    the bound)."""
    for name in names:
        _require_number(name, getattr(params, name), ">= 0", unit, lambda value: value >= 0)


def _require_number(name: str, value, bound: str, unit: str, holds) -> None:
    """Raise ``InputError`` for field ``name`` unless ``value`` is a finite real number (not a
    bool) for which ``holds(value)``."""
    if not (isinstance(value, numbers.Real) and not isinstance(value, bool)
            and math.isfinite(value) and holds(value)):
        raise InputError(None, name, f"must be {bound}{unit}, got {value!r}")


def require_choice(params, name: str, choices) -> None:
    """Field ``name`` of ``params`` one of ``choices``."""
    value = getattr(params, name)
    if value not in choices:
        raise InputError(None, name, f"must be one of {', '.join(choices)}, got {value!r}")
