"""The one check of the solver options' fields: each value of the type its field declares.

The options dataclasses (``solvers.qp.Options``, ``solvers.nlp.Options``, ``solvers.mrf.Options``) check their
ranges in ``__post_init__``; a value of another type (``max_iter="10"``) had failed there with Python's own
``TypeError: '<' not supported between instances of 'str' and 'int'``. :func:`check_fields` runs first and says
which field wants what, as :class:`~solvers.errors.InvalidOptions`.
"""

from __future__ import annotations

import dataclasses
import numbers
import types
import typing

from solvers.errors import InvalidOptions

_ACCEPTS: dict[type, typing.Callable[[object], bool]] = {
    bool: lambda v: isinstance(v, bool),
    int: lambda v: isinstance(v, numbers.Integral) and not isinstance(v, bool),
    float: lambda v: isinstance(v, numbers.Real) and not isinstance(v, bool),
    str: lambda v: isinstance(v, str),
}


_HINTS: dict[type, dict[str, typing.Any]] = {}  # each options class's declared field types, resolved once


def check_fields(options: object) -> None:
    """Raise :class:`InvalidOptions` naming the first field of the dataclass ``options`` whose value is not of its
    declared type (``int``, ``float``, ``bool``, ``str``, or one of them or None)."""
    cls = type(options)
    hints = _HINTS.get(cls) or _HINTS.setdefault(cls, typing.get_type_hints(cls))
    for field in dataclasses.fields(options):  # type: ignore[arg-type]
        hint, value = hints[field.name], getattr(options, field.name)
        kinds = typing.get_args(hint) if isinstance(hint, types.UnionType) else (hint,)
        if value is None and type(None) in kinds:
            continue
        tests = [_ACCEPTS[k] for k in kinds if k in _ACCEPTS]
        if tests and not any(test(value) for test in tests):
            want = " or ".join("None" if k is type(None) else k.__name__ for k in kinds)
            raise InvalidOptions(f"{type(options).__name__}.{field.name} = {value!r}: must be {want}")
