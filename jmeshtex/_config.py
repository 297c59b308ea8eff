"""One mechanism for every configuration dataclass: declarative validation, a JSON round trip, ``replace``.

A config is a frozen dataclass that derives from :class:`ConfigBase` and lists its checks in a
``_RULES`` table, checked in order in ``__post_init__``; the first one broken raises
:class:`~jmeshtex.ConfigError` with that rule's message. Two kinds of rule:

- :func:`rule` (one value): every field named in ``names`` must satisfy ``ok(value)``;
- :func:`cross_rule` (several values): the whole config must satisfy ``ok(config)``.

Messages are ``str.format`` templates. A field rule's template sees ``{cls}`` (the class name, with
its method package for a library config: ``dgts.Config``),
``{name}``, ``{value}``, ``{must}`` (the rule's requirement) and ``{c}`` (the config); without its
own template it uses the class's ``_MESSAGE`` (default ``"{cls}.{name} must be {must}, got {value!r}"``).
A cross rule's template sees ``{cls}`` and ``{c}`` (``"{c.lo} > {c.hi}"``), or it is a function of
the config for messages that need computed values. A predicate that raises ``TypeError``,
``ValueError`` or ``ArithmeticError`` (a string where a number belongs, ``len`` of an int,
``10**400`` as a float) counts as broken, so a wrongly typed value gets the rule's message too,
never a bare built-in error.

After the ``_RULES``, every field is checked against its annotation (:func:`type_ok`): an ``int``
field takes an integer (``np.integer`` too, never a bool) below ``2**31``, a ``float`` field a
finite number, a ``bool`` field True or False, a ``str`` field a string, a tuple field a tuple of
such values; ``X | None`` also takes None. So every field of every config has at least a type and
finiteness rule, and ``_RULES`` add the ranges. Before any check, NumPy scalars become Python
scalars and lists (or 1-D arrays) given for tuple fields become tuples, so a config stays hashable
and writes plain JSON.

:meth:`ConfigBase.to_dict` writes plain JSON values (tuples become lists); :meth:`ConfigBase.from_dict`
reads them back: lists become tuples for fields annotated with a tuple type, missing keys take their
defaults (so older files and partial JSON still load) and unknown keys raise
:class:`~jmeshtex.ConfigError` naming them.

A field annotated with another :class:`ConfigBase` class is a *section* (a method's
``experimental`` switches): it is validated by its own rules, and the config reads as one flat
namespace, so section fields' names must be unique across the config. :meth:`~ConfigBase.to_dict`
and :meth:`~ConfigBase.fingerprint` write a section's fields in its place, by their own names (a
field moved into a section leaves model files and checkpoint fingerprints unchanged);
:meth:`~ConfigBase.from_dict` and :meth:`~ConfigBase.replace` take a section's field by its own name
(``schedule_shift=2.0``), by its dotted path (``"experimental.schedule_shift"``), or the whole
section (``experimental=Experimental(...)`` or a dict of its fields); so does the constructor.

Example:
  >>> import dataclasses
  >>> @dataclasses.dataclass(frozen=True)
  ... class Box(ConfigBase):
  ...     size: tuple[int, int] = (2, 3)
  ...     scale: float = 1.0
  ...     _RULES = (
  ...         rule("scale", lambda x: x > 0, "> 0"),
  ...         cross_rule(lambda c: len(c.size) == 2, "{cls}.size must be two numbers, got {c.size!r}"),
  ...     )
  >>> Box().to_dict()
  {'size': [2, 3], 'scale': 1.0}
  >>> Box.from_dict({"size": [4, 5]})
  Box(size=(4, 5), scale=1.0)
  >>> Box(scale=0)
  Traceback (most recent call last):
  ...
  jmeshtex._errors.ConfigError: Box.scale must be > 0, got 0
"""

from __future__ import annotations

import collections
import dataclasses
import functools
import math
import sys
import types
import typing
from collections.abc import Callable, Mapping
from typing import Any, ClassVar, TypeVar, Union

import numpy as np

from ._errors import ConfigError

#: the bound of an ``int`` field (exclusive): JAX's default integer is int32
INT_LIMIT = 2**31

#: a message template (``str.format``), or a function of the config for a cross rule
Message = str | Callable[[Any], str]

_C = TypeVar("_C", bound="ConfigBase")


@dataclasses.dataclass(frozen=True)
class Rule:
    """One validation rule; build it with :func:`rule` or :func:`cross_rule`.

    Attributes:
      names: the fields checked one by one with ``ok(value)``; empty for a rule over the whole
        config, checked with ``ok(config)``.
      ok: the predicate; False, or a ``TypeError`` / ``ValueError`` raised by it, breaks the rule.
      must: what the predicate requires, for the ``{must}`` of the message (field rules).
      message: the message template, or a function of the config; None: the class's ``_MESSAGE``.
    """

    names: tuple[str, ...]
    ok: Callable[[Any], bool]
    must: str = ""
    message: Message | None = None

    def check(self, config: Any) -> None:
        """Raise :class:`~jmeshtex.ConfigError` with this rule's message if ``config`` breaks it."""
        cls = display_name(type(config))
        if not self.names:
            if not _holds(self.ok, config):
                message = self.message
                raise ConfigError(
                    message(config) if callable(message) else str(message).format(cls=cls, c=config)
                )
            return
        template = self.message if self.message is not None else type(config)._MESSAGE
        for name in self.names:
            value = getattr(config, name)
            if not _holds(self.ok, value):
                raise ConfigError(
                    template.format(
                        cls=cls, name=name, value=_shown(value), must=self.must, c=config
                    )
                )


class _Huge(int):
    """An integer too long to print in a message: shown as its digit count."""

    def __repr__(self) -> str:
        return f"<an integer of {len(str(abs(int(self))))} digits>"

    __str__ = __repr__


def _shown(value: Any) -> Any:
    """``value`` as a message shows it: an integer of more than 30 digits by its length."""
    if isinstance(value, int) and not isinstance(value, bool) and abs(value) >= 10**30:
        return _Huge(value)
    return value


def _holds(ok: Callable[[Any], bool], arg: Any) -> bool:
    try:
        return bool(ok(arg))
    except (TypeError, ValueError, ArithmeticError):
        return False


def display_name(cls: type) -> str:
    """A config class's name in messages: ``meshmatch.Config`` for a method's config, else the class name.

    Example:
      >>> from jmeshtex.dgts import Config
      >>> display_name(Config)
      'dgts.Config'
    """
    parts = cls.__module__.split(".")
    if len(parts) > 1 and parts[0] == "jmeshtex" and not parts[1].startswith("_"):
        return f"{parts[1]}.{cls.__qualname__}"
    return cls.__qualname__


def rule(
    names: str, ok: Callable[[Any], bool], must: str = "", *, message: str | None = None
) -> Rule:
    """A rule on single values: each field in ``names`` (separated by spaces) must satisfy ``ok``.

    Args:
      names: field names separated by spaces, e.g. ``"lr scale_factor"``.
      ok: predicate of one value.
      must: the requirement in words (``"> 0"``), the ``{must}`` of the message.
      message: a template with ``{cls}``, ``{name}``, ``{value}``, ``{must}``, ``{c}``; None: the
        class's ``_MESSAGE``.

    Returns:
      The rule, for a ``_RULES`` table.

    Example:
      >>> rule("lr scale_factor", lambda x: x > 0, "> 0").names
      ('lr', 'scale_factor')
    """
    fields = tuple(names.split())
    if not fields:
        raise ConfigError(
            "rule() needs at least one field name; use cross_rule() for a rule over the whole config"
        )
    return Rule(fields, ok, must, message)


def cross_rule(ok: Callable[[Any], bool], message: Message) -> Rule:
    """A rule over the whole config (several fields together): ``ok(config)`` must hold.

    Args:
      ok: predicate of the config.
      message: a template with ``{cls}`` and ``{c}`` (the config: ``{c.min_size}``), or a function
        of the config returning the message.

    Returns:
      The rule, for a ``_RULES`` table.

    Example:
      >>> r = cross_rule(lambda c: c.lo <= c.hi, "need lo <= hi, got {c.lo}, {c.hi}")
      >>> r.names
      ()
    """
    return Rule((), ok, "", message)


def is_int(x: Any, low: int | None = None) -> bool:
    """Whether ``x`` is an integer (``int`` or ``np.integer``, not a bool), and ``>= low`` if given.

    The one integer check of the package: arguments and config fields use it.

    Args:
      x: any value.
      low: the smallest value accepted; None: no bound.

    Returns:
      True for an integer (at least ``low``), False otherwise (never raises).

    Example:
      >>> is_int(3), is_int(np.int64(3)), is_int(True), is_int(3.0), is_int(0, low=1)
      (True, True, False, False, False)
    """
    if isinstance(x, (bool, np.bool_)) or not isinstance(x, (int, np.integer)):
        return False
    return low is None or x >= low


def is_finite_number(x: Any) -> bool:
    """Whether ``x`` is a real number (``int``, ``float`` or a NumPy one, not a bool) and finite.

    Example:
      >>> is_finite_number(0.5), is_finite_number(float("inf")), is_finite_number("1")
      (True, False, False)
      >>> is_finite_number(10**400), is_finite_number(True)
      (False, False)
    """
    if isinstance(x, (bool, np.bool_)) or not isinstance(x, (int, float, np.integer, np.floating)):
        return False
    try:
        return math.isfinite(x)
    except OverflowError:  # an int too large for a float
        return False


def integers(names: str, low: int) -> Rule:
    """A rule: each field in ``names`` must be an integer (not a bool) ``>= low``.

    Example:
      >>> integers("size steps", 1).must
      'an integer >= 1'
    """
    return rule(names, lambda x: is_int(x, low), f"an integer >= {low}")


def type_ok(hint: Any, value: Any) -> bool:
    """Whether ``value`` fits the field annotation ``hint`` (the type rule every config field gets).

    ``int``: an integer (not a bool) in ``(-2**31, 2**31)``; ``float``: a finite number; ``bool``:
    True or False; ``str``: a string; ``tuple[X, ...]`` / ``tuple[X, Y]``: a tuple of such values;
    ``X | Y``: either; ``None``: None. Any other annotation accepts every value.

    Args:
      hint: a resolved annotation (``typing.get_type_hints``).
      value: the field's value.

    Returns:
      Whether the value fits.

    Example:
      >>> type_ok(int, 3), type_ok(int, 1.5), type_ok(float, float("nan")), type_ok(bool, 1)
      (True, False, False, False)
      >>> type_ok(tuple[int, int], (1, 2)), type_ok(tuple[float, ...] | None, None)
      (True, True)
    """
    origin = typing.get_origin(hint)
    if origin in (Union, types.UnionType):
        return any(type_ok(a, value) for a in typing.get_args(hint))
    if hint is type(None) or hint is None:
        return value is None
    if _is_section(hint):
        return type(value) is hint
    if hint is bool:
        return isinstance(value, bool)
    if hint is int:
        return is_int(value) and -INT_LIMIT < value < INT_LIMIT
    if hint is float:
        return is_finite_number(value)
    if hint is str:
        return isinstance(value, str)
    if hint is tuple or origin is tuple:
        if not isinstance(value, tuple):
            return False
        args = typing.get_args(hint)
        if not args:
            return True
        if len(args) == 2 and args[1] is Ellipsis:
            return all(type_ok(args[0], v) for v in value)
        return len(value) == len(args) and all(
            type_ok(a, v) for a, v in zip(args, value, strict=True)
        )
    return True


def type_words(hint: Any) -> str:
    """What :func:`type_ok` asks of a value of annotation ``hint``, in words (for messages).

    Example:
      >>> type_words(int), type_words(tuple[float, float, float] | str | None)
      ('an integer below 2**31', 'a tuple of 3 finite numbers, a string or None')
    """
    origin = typing.get_origin(hint)
    if origin in (Union, types.UnionType):
        words = [type_words(a) for a in typing.get_args(hint)]
        return ", ".join(words[:-1]) + " or " + words[-1] if len(words) > 1 else words[0]
    if hint is type(None) or hint is None:
        return "None"
    if _is_section(hint):
        return f"a {display_name(hint)} (or a dict of its fields)"
    if hint is tuple or origin is tuple:
        args = typing.get_args(hint)
        if not args:
            return "a tuple"
        if len(args) == 2 and args[1] is Ellipsis:
            return f"a tuple of {_plural(args[0])}"
        if len(set(args)) == 1:
            return f"a tuple of {len(args)} {_plural(args[0])}"
        return "a tuple (" + ", ".join(type_words(a) for a in args) + ")"
    return _WORDS.get(hint, getattr(hint, "__name__", str(hint)))


_WORDS = {
    int: "an integer below 2**31",
    float: "a finite number",
    bool: "True or False",
    str: "a string",
}


def _plural(hint: Any) -> str:
    return {int: "integers", float: "finite numbers", bool: "bools", str: "strings"}.get(
        hint, type_words(hint)
    )


def _normalise(hint: Any, value: Any) -> Any:
    """NumPy scalars and 0-d NumPy / JAX arrays as Python scalars; a list or 1-D array given for a
    tuple field as a tuple; a dict given for a section as that section (:meth:`ConfigBase.from_dict`)."""
    if _is_section(hint) and isinstance(value, Mapping):
        return hint.from_dict(value)
    if isinstance(value, np.generic):
        return value.item()
    if type(value).__module__.split(".")[0] in ("numpy", "jax", "jaxlib") and np.ndim(value) == 0:
        return value.item()
    if isinstance(value, np.ndarray) and value.ndim == 1 and _is_tuple_type(hint):
        return tuple(v.item() for v in value)
    if isinstance(value, list) and _is_tuple_type(hint):
        return tuple(_normalise(None, v) for v in value)
    if isinstance(value, tuple):
        return tuple(_normalise(None, v) for v in value)
    return value


class _Flat(type):
    """The metaclass of :class:`ConfigBase`: a config with sections also takes their fields by their
    own names (or dotted paths) as keyword arguments, like :meth:`ConfigBase.replace`; and a config
    class's annotations are read in the namespace its ``class`` statement ran in (:func:`_hints`)."""

    def __init__(cls, name: str, bases: tuple[type, ...], namespace: dict[str, Any]) -> None:
        super().__init__(name, bases, namespace)
        frame = sys._getframe(1)  # the module (or function) body running the class statement
        cls._defined_in = collections.ChainMap(frame.f_locals, frame.f_globals)

    def __call__(cls, *args: Any, **kwargs: Any) -> Any:
        if kwargs and _sections(cls):
            kwargs = _routed(cls, kwargs, None)
        return super().__call__(*args, **kwargs)


class ConfigBase(metaclass=_Flat):
    """Base of the frozen config dataclasses: rules checked on creation, JSON round trip, ``replace``.

    Subclasses are ``@dataclasses.dataclass(frozen=True)`` and set ``_RULES`` (and ``_MESSAGE`` for
    their own wording of field rules); see the module docstring.
    """

    _RULES: ClassVar[tuple[Rule, ...]] = ()
    _MESSAGE: ClassVar[str] = "{cls}.{name} must be {must}, got {value!r}"
    #: fields a run may change when it resumes from a checkpoint (step counts, checkpoint cadence):
    #: left out of :meth:`fingerprint`
    _RESUMABLE: ClassVar[frozenset[str]] = frozenset()

    def __post_init__(self) -> None:
        hints = _hints(type(self))
        for f in dataclasses.fields(self):  # type: ignore[arg-type]
            value = getattr(self, f.name)
            normal = _normalise(hints.get(f.name), value)
            if normal is not value:
                object.__setattr__(self, f.name, normal)
        sections = _sections(type(self))
        if sections:
            _owners(type(self))  # refuses a section field named like another field
        self._check_types(hints, sections)  # sections first: the rules may read their fields
        for r in self._RULES:
            r.check(self)
        self._check_types(hints, [f.name for f in dataclasses.fields(self)])  # type: ignore[arg-type]

    def _check_types(self, hints: dict[str, Any], names: Any) -> None:
        for name in names:
            hint = hints.get(name)
            value = getattr(self, name)
            if hint is not None and not type_ok(hint, value):
                raise ConfigError(
                    self._MESSAGE.format(
                        cls=display_name(type(self)),
                        name=name,
                        value=_shown(value),
                        must=type_words(hint),
                        c=self,
                    )
                )

    def __repr__(self) -> str:
        """``Name(field=value, ...)`` over the flat names, a section's fields in its place (the
        dataclass ``repr`` of the same config before its fields moved into the section), for a
        config declared with ``dataclass(repr=False)``."""
        return f"{type(self).__qualname__}({', '.join(f'{k}={v!r}' for k, v in _flat_items(self))})"

    def to_dict(self) -> dict[str, Any]:
        """The fields as a JSON-compatible dict (tuples become lists), a section's fields in its
        place by their own names (module docstring)."""
        out: dict[str, Any] = {}
        for f in dataclasses.fields(self):  # type: ignore[arg-type]
            value = getattr(self, f.name)
            if isinstance(value, ConfigBase) and f.name in _sections(type(self)):
                out.update(value.to_dict())
            else:
                out[f.name] = _plain(value)
        return out

    @classmethod
    def from_dict(cls: type[_C], data: Mapping[str, Any]) -> _C:
        """Rebuild from :meth:`to_dict` output; missing keys take their defaults.

        A section's fields are read by their own names, by their dotted paths
        (``"experimental.schedule_shift"``) or as a dict under the section's name.

        Raises:
          ConfigError: ``data`` is not a mapping, has unknown keys, or holds invalid values.
        """
        if not isinstance(data, Mapping):
            raise ConfigError(
                f"{display_name(cls)}.from_dict needs a dict of fields (as written by to_dict), "
                f"got {type(data).__name__}"
            )
        tuples = _tuple_fields(cls)
        data = {k: tuple(v) if k in tuples and isinstance(v, list) else v for k, v in data.items()}
        return cls(**_routed(cls, data, None))

    def fingerprint(self) -> dict[str, Any]:
        """The fields a checkpoint must have been written with to be resumed under this config:
        :meth:`to_dict` without the class's ``_RESUMABLE`` fields. Every method's checkpoint
        fingerprint takes its config part from here, so one rule decides what a resumption may change.

        Example:
          >>> import dataclasses
          >>> @dataclasses.dataclass(frozen=True)
          ... class Run(ConfigBase):
          ...     width: int = 8
          ...     steps: int = 100
          ...     _RESUMABLE = frozenset({"steps"})
          >>> Run(steps=200).fingerprint() == Run().fingerprint()
          True
        """
        return {k: v for k, v in self.to_dict().items() if k not in self._RESUMABLE}

    def replace(self: _C, **changes: Any) -> _C:
        """A copy with some fields changed (validated again); unknown names raise ConfigError.

        A section's field may be named by its own name or its dotted path
        (``replace(**{"experimental.remat": True})``, as a command line's ``--set`` gives it).
        """
        return dataclasses.replace(self, **_routed(type(self), changes, self))  # type: ignore[type-var]


def flat_names(cls: type) -> tuple[str, ...]:
    """The names :meth:`ConfigBase.to_dict` writes for config class ``cls``: its fields, a section's
    fields (recursively) in the section's place.

    Raises:
      ConfigError: a name occurs twice (a section field named like another field).

    Example:
      >>> from jmeshtex.dgts import Config
      >>> flat_names(Config)[:3]
      ('num_layers', 'start_features', 'min_features')
    """
    return tuple(_owners(cls))


def _flat_items(config: Any) -> list[tuple[str, Any]]:
    items = []
    for f in dataclasses.fields(config):
        value = getattr(config, f.name)
        if f.name in _sections(type(config)):
            items.extend(_flat_items(value))
        else:
            items.append((f.name, value))
    return items


def _routed(cls: type, changes: Mapping[str, Any], current: Any) -> dict[str, Any]:
    """``changes`` (flat, dotted or whole-section names) as keyword arguments of ``cls`` (or of
    :func:`dataclasses.replace` of ``current``), each section's changes applied to its value."""
    owners, sections = _owners(cls), _sections(cls)
    out: dict[str, Any] = {}
    inner: dict[str, dict[str, Any]] = {}
    unknown = []
    for name, value in changes.items():
        head, dot, rest = name.partition(".") if isinstance(name, str) else (name, "", "")
        if dot and head in sections:
            inner.setdefault(head, {})[rest] = value
        elif not dot and name in sections:
            out[name] = value
        elif not dot and owners.get(name, "") is None:
            out[name] = value
        elif not dot and name in owners:
            inner.setdefault(owners[name], {})[name] = value
        else:
            unknown.append(name)
    if unknown:
        raise ConfigError(
            f"{display_name(cls)}: unknown fields {sorted(unknown, key=str)}; "
            f"known: {sorted(owners)}"
        )
    for section, fields in inner.items():
        base = out.get(section, getattr(current, section, None))
        if isinstance(base, Mapping):
            out[section] = sections[section].from_dict({**base, **fields})
        elif isinstance(base, ConfigBase):
            out[section] = base.replace(**fields)
        else:
            out[section] = sections[section].from_dict(fields)
    return out


@functools.cache
def _sections(cls: type) -> dict[str, type]:
    """The section fields of ``cls`` (annotated with a :class:`ConfigBase` class) and their classes."""
    hints = _hints(cls)
    return {
        f.name: hints[f.name] for f in dataclasses.fields(cls) if _is_section(hints.get(f.name))
    }


@functools.cache
def _owners(cls: type) -> dict[str, str | None]:
    """Every flat name of ``cls`` and the section holding it (None: a field of ``cls`` itself)."""
    owners: dict[str, str | None] = {}
    sections = _sections(cls)
    for f in dataclasses.fields(cls):
        names = _owners(sections[f.name]) if f.name in sections else {f.name: None}
        for name in names:
            if name in owners:
                raise ConfigError(
                    f"{display_name(cls)}: the name {name!r} occurs twice among its fields and "
                    "its sections' fields; a section's field names must be unique in the config"
                )
            owners[name] = f.name if f.name in sections else None
    return owners


def _is_section(hint: Any) -> bool:
    return isinstance(hint, type) and issubclass(hint, ConfigBase)


def stored_config(cls: type[_C], data: Mapping[str, Any], where: Any) -> _C:
    """The config a model file or checkpoint stored: every field must be there (no defaults filled
    in, so a file never reads as trained with settings it was not), none unknown.

    Args:
      cls: the config class.
      data: the stored dict (:meth:`ConfigBase.to_dict` output).
      where: the file, for the message.

    Raises:
      ConfigError: fields missing, unknown or invalid; the message names them and the file.

    Example:
      >>> from jmeshtex.surfacecnn import Config
      >>> stored_config(Config, {"size": 8}, "m.npz")
      Traceback (most recent call last):
      ...
      jmeshtex._errors.ConfigError: m.npz: its stored surfacecnn.Config lacks fields [...
    """
    if isinstance(data, Mapping):
        missing = sorted(set(flat_names(cls)) - set(data))
        if missing:
            raise ConfigError(
                f"{where}: its stored {display_name(cls)} lacks fields {missing} (written by "
                "an earlier jmeshtex version); convert it once with that version's values"
            )
    return cls.from_dict(data)


def _plain(value: Any) -> Any:
    return [_plain(v) for v in value] if isinstance(value, (tuple, list)) else value


@functools.cache
def _hints(cls: type) -> dict[str, Any]:
    """``cls``'s resolved annotations, names looked up first where its ``class`` statement ran: a
    section's class is then the one the config was defined with, even when ``sys.modules`` holds a
    second copy of the module by now (pytest's ``--import-mode=importlib`` runs a module file of
    the doctests again under its own name)."""
    return typing.get_type_hints(cls, localns=getattr(cls, "_defined_in", None))


@functools.cache
def _tuple_fields(cls: type) -> frozenset[str]:
    hints = _hints(cls)
    return frozenset(f.name for f in dataclasses.fields(cls) if _is_tuple_type(hints.get(f.name)))


def _is_tuple_type(hint: Any) -> bool:
    origin = typing.get_origin(hint)
    if hint is tuple or origin is tuple:
        return True
    return origin in (Union, types.UnionType) and any(
        _is_tuple_type(a) for a in typing.get_args(hint)
    )
