"""One ``to_dict`` / ``from_dict`` / ``digest`` for every frozen configuration dataclass.

:class:`Config` is a mixin: a frozen dataclass that inherits it round-trips through JSON
(nested configs as dicts, tuples as lists) and refuses unknown keys when read back.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import types
import typing
from typing import TYPE_CHECKING, Any, TypeVar, Union, get_args, get_origin

if TYPE_CHECKING:  # typing.Self is 3.11+; typing_extensions is only needed by type checkers
    from typing_extensions import Self

C = TypeVar("C", bound="Config")


def _encode(value: Any) -> Any:
    if isinstance(value, Config):
        return value.to_dict()
    if isinstance(value, (tuple, list)):
        return [_encode(v) for v in value]
    return value


def _decode(tp: Any, value: Any) -> Any:
    """``value`` (from JSON) as the field type ``tp`` wants it: dicts of configs become the
    config, lists become tuples; everything else is left to the dataclass's own checks."""
    if value is None:
        return None
    origin = get_origin(tp)
    if origin is Union or origin is types.UnionType:
        for arg in get_args(tp):
            if arg is type(None):
                continue
            if isinstance(value, dict) and isinstance(arg, type) and issubclass(arg, Config):
                return arg.from_dict(value)
            if isinstance(value, list) and get_origin(arg) is tuple:
                return _decode(arg, value)
        return value
    if isinstance(tp, type) and issubclass(tp, Config) and isinstance(value, dict):
        return tp.from_dict(value)
    if origin is tuple and isinstance(value, (list, tuple)):
        args = get_args(tp)
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_decode(args[0], v) for v in value)
        if args and len(args) == len(value):
            return tuple(_decode(a, v) for a, v in zip(args, value))
        return tuple(value)
    return value


def _type_name(tp: Any) -> str:
    return tp.__name__ if isinstance(tp, type) else str(tp).replace("typing.", "")


def _type_ok(tp: Any, value: Any) -> bool:
    """``value`` (from JSON) is of the field type ``tp`` as far as JSON can say: an ``int``
    field takes whole numbers of type ``int`` only (``16.5``, ``64.0`` and ``true`` are not),
    a ``float`` field numbers (not ``true``), a ``str`` field strings; unions take what one
    of their types takes; other types (literals, tuples, configs) are left to the class."""
    if tp is int:
        return isinstance(value, int) and not isinstance(value, bool)
    if tp is float:
        return isinstance(value, (int, float)) and not isinstance(value, bool)
    if tp is str:
        return isinstance(value, str)
    if tp is bool:
        return isinstance(value, bool)
    origin = get_origin(tp)
    if origin is Union or origin is types.UnionType:
        return any(arg is not type(None) and _type_ok(arg, value) for arg in get_args(tp)) or (
            value is None and type(None) in get_args(tp))
    if origin is tuple and isinstance(value, (list, tuple)):
        args = get_args(tp)
        if len(args) == 2 and args[1] is Ellipsis:
            return all(_type_ok(args[0], v) for v in value)
        return len(args) != len(value) or all(_type_ok(a, v) for a, v in zip(args, value))
    return True


class Config:
    """Mixin of the frozen configuration dataclasses: :meth:`to_dict`, :meth:`from_dict` and
    :meth:`digest`. ``_OMIT_NONE`` names fields left out of :meth:`to_dict` while ``None``, and
    ``_OMIT_DEFAULT`` fields left out while at the value it gives them (so a dict written before
    such a field existed is still the same dict). ``_RETIRED`` maps the fields of a deleted stage
    to the dict value they had while it was off: :meth:`from_dict` drops such a key holding that
    value and refuses one holding another (the stage is gone), and :meth:`digest_dict` (what
    :meth:`digest` hashes) still holds those that were written (all but a ``None`` of a field
    named in ``_OMIT_NONE``), so the digest of a config is what it was before the stage was
    deleted."""

    _OMIT_NONE: typing.ClassVar[tuple[str, ...]] = ()
    _OMIT_DEFAULT: typing.ClassVar[typing.Mapping[str, Any]] = types.MappingProxyType({})
    _RETIRED: typing.ClassVar[typing.Mapping[str, Any]] = types.MappingProxyType({})

    def to_dict(self) -> dict[str, Any]:
        """The fields as JSON-able values: nested configs as dicts, tuples as lists."""
        out = {}
        for f in dataclasses.fields(self):  # type: ignore[arg-type]
            v = getattr(self, f.name)
            if v is None and f.name in self._OMIT_NONE:
                continue
            if f.name in self._OMIT_DEFAULT and v == self._OMIT_DEFAULT[f.name]:
                continue
            out[f.name] = _encode(v)
        return out

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Self:
        """The config of ``d`` (as :meth:`to_dict` gives it; missing keys take their
        defaults). ``ValueError`` for a key that is not a field, or a value not of its field's
        type (``orientations: 16.5``, ``window: 64.0``: a number's type is checked here, once,
        for every config read from a file)."""
        if not isinstance(d, dict):
            raise ValueError(f"{cls.__name__} must be a JSON object, got {type(d).__name__}")
        names = {f.name for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
        for k in sorted(set(d) & set(cls._RETIRED) - names):
            if d[k] != cls._RETIRED[k]:
                raise ValueError(f"{cls.__name__}.{k}: this stage was deleted (docs/accuracy.md, "
                                 f"'Deleted stages'); only its off value {json.dumps(cls._RETIRED[k])[:40]} is read")
            d = {key: v for key, v in d.items() if key != k}
        unknown = set(d) - names
        if unknown:
            raise ValueError(f"unknown {cls.__name__} fields: {sorted(unknown)}")
        hints = typing.get_type_hints(cls)
        for k, v in d.items():
            if not _type_ok(hints.get(k), v):
                raise ValueError(f"{cls.__name__}.{k} must be of type {_type_name(hints.get(k))}, "
                                 f"got {type(v).__name__} {json.dumps(v)[:40]}")
        return cls(**{k: _decode(hints.get(k), v) for k, v in d.items()})

    def digest_dict(self) -> dict[str, Any]:
        """:meth:`to_dict` with the deleted stages' fields at their off values (``_RETIRED``),
        nested configs' by their own :meth:`digest_dict`: what :meth:`digest` hashes."""
        out = {**{k: v for k, v in self._RETIRED.items() if not (v is None and k in self._OMIT_NONE)},
               **self.to_dict()}
        for f in dataclasses.fields(self):  # type: ignore[arg-type]
            v = getattr(self, f.name)
            if isinstance(v, Config) and f.name in out:
                out[f.name] = v.digest_dict()
        return out

    def digest(self) -> str:
        """16 hex digits of the SHA-256 of :meth:`digest_dict` as canonical JSON: equal configs
        give equal digests, run after run."""
        text = json.dumps(self.digest_dict(), sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()[:16]
