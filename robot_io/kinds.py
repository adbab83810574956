"""One way to register a kind of device, for ``[hand_source]``, ``[arm]`` and ``[gripper]``
(``docs/hardware.md``): the table's ``kind`` chooses a model, one pydantic model per kind with its own
keys and defaults, from a :class:`Kinds` registry; the model also says what opens that kind.

A key of another kind is refused naming the kind it belongs to, unless it holds that kind's default:
a table written before the kinds had tables of their own (and every session stored then) lists
every kind's keys, and a default says nothing. A kind that does not exist is refused listing the
kinds.

A new kind is one model (in its device's room, with what opens it) and one line in its registry:
``HAND_SOURCES``, ``ARMS`` or ``GRIPPERS``. :meth:`Kinds.added` registers one for a while (a test's
kind, a lab's own device under trial).
"""

from __future__ import annotations

import threading
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from typing import Annotated, Any, ClassVar, Generic, TypeVar, get_args

from pydantic import BeforeValidator, SerializeAsAny
from pydantic_core import PydanticUndefined, to_jsonable_python

from robot_io.bounds import Frozen
from robot_io.errors import ConfigError


class DeviceKind(Frozen):
    """What every kind's model has: its ``kind``, and whether it needs no hardware."""

    #: Runs on simulated time: no hardware, nothing on the wall clock (the mock arm, the simulated
    #: hand, no gripper).
    simulated: ClassVar[bool] = False

    kind: str


M = TypeVar("M", bound=DeviceKind)


def kind_of(model: type[DeviceKind]) -> str:
    """The ``kind`` a model is chosen by (its ``kind: Literal[...]`` field)."""
    return get_args(model.model_fields["kind"].annotation)[0]


def _plain(value: Any) -> Any:
    """A value as TOML or JSON gives it (tuples as lists), to compare with a default."""
    return to_jsonable_python(value)


class Kinds(Generic[M]):
    """The kinds of the table ``[table]``, by their ``kind``; ``default``: the kind of a table that
    names none."""

    def __init__(self, table: str, default: str, *models: type[M]) -> None:
        self.table, self.default = table, default
        self._models: dict[str, type[M]] = {}
        self._lock = threading.Lock()
        for model in models:
            self.register(model)

    # -- the registry ------------------------------------------------------------------------------
    def register(self, model: type[M]) -> None:
        kind = kind_of(model)
        with self._lock:
            if kind in self._models:
                raise ValueError(f"[{self.table}] kind = {kind!r} is registered already")
            self._models = {**self._models, kind: model}  # replaced whole: readers need no lock

    @contextmanager
    def added(self, model: type[M]) -> Iterator[type[M]]:
        """``model`` registered until the ``with`` block ends (a test's kind, a device under trial)."""
        self.register(model)
        try:
            yield model
        finally:
            with self._lock:
                self._models = {k: m for k, m in self._models.items() if m is not model}

    def __getitem__(self, kind: str) -> type[M]:
        return self._models[kind]

    def __contains__(self, kind: object) -> bool:
        return kind in self._models

    def __iter__(self) -> Iterator[str]:
        return iter(self._models)

    def __len__(self) -> int:
        return len(self._models)

    def items(self) -> list[tuple[str, type[M]]]:
        return list(self._models.items())

    # -- tables -----------------------------------------------------------------------------------
    def defaults(self, kind: str) -> dict[str, Any]:
        """``kind``'s keys with a default, as JSON gives them (a required key has none)."""
        return {name: _plain(field.default) for name, field in self._models[kind].model_fields.items()
                if field.default is not PydanticUndefined}

    def own_keys(self, table: Mapping[str, Any]) -> dict[str, Any]:
        """A table (as stored) with its kind's keys only: one written when every kind's keys stood
        in one table compares equal to the same device written now."""
        model = self._models.get(table.get("kind", self.default))
        return {key: value for key, value in table.items() if model is None or key in model.model_fields}

    def as_kind(self, device: DeviceKind, kind: str, **update: Any) -> M:
        """``device``'s table as ``kind``'s, validated anew: every key both kinds have is kept,
        ``update`` is applied."""
        model = self._models[kind]
        kept = {key: value for key, value in device.model_dump().items() if key in model.model_fields}
        return model.model_validate({**kept, **update, "kind": kind})

    def _foreign_key(self, key: str, value: Any, kind: str) -> str | None:
        """Why ``key`` cannot stand in a table of ``kind``; None: it may (a default of another kind,
        from a table written when every kind's keys stood in one table), or pydantic says it is
        unknown."""
        models = self._models
        owners = [other for other, model in models.items() if key in model.model_fields]
        if owners:
            defaults = [models[owner].model_fields[key].default for owner in owners]
            if all(d is not PydanticUndefined and _plain(d) == _plain(value) for d in defaults):
                return None
            kinds = " or ".join(f'kind = "{owner}"' for owner in owners)
            return (f'[{self.table}] {key} is a key of {kinds}, not of kind = "{kind}": remove it, '
                    "or set the kind it belongs to")
        prefix = key.split("_", 1)[0]
        if prefix in models and prefix != kind:
            keys = ", ".join(name for name in models[prefix].model_fields if name.startswith(prefix))
            return (f'[{self.table}] {key} is no key of kind = "{kind}"; it reads like one of kind = '
                    f'"{prefix}", whose keys are {keys}')
        return None

    def validate(self, value: Any) -> Any:
        """The model of the table's ``kind`` (:attr:`default` when it names none), validated on its
        own fields; a kind that does not exist or a key of another kind is refused here, in words."""
        if not isinstance(value, Mapping):
            return value
        table = {"kind": self.default, **value}
        kind, models = table["kind"], self._models
        if kind not in models:
            raise ConfigError(f"[{self.table}] kind = {kind!r} is no {self.table.replace('_', ' ')}; "
                              "the kinds are " + ", ".join(f'"{name}"' for name in models))
        for key in [key for key in table if key not in models[kind].model_fields]:
            refusal = self._foreign_key(key, table[key], kind)
            if refusal is not None:
                raise ConfigError(refusal)
            if any(key in model.model_fields for model in models.values()):
                del table[key]
        return models[kind].model_validate(table)

    def field(self, base: type[M]) -> Any:
        """The type of a configuration's field holding a table of one of these kinds: validated by
        :meth:`validate` (so a kind registered later is read too), written with its kind's keys."""
        return Annotated[SerializeAsAny[base], BeforeValidator(self.validate)]  # type: ignore[misc,valid-type]
