"""Name -> (config schema, implementation) registries, one per config group (robomimic's pattern).

Every config node of a registered group carries ``name``; :meth:`Registry.validate` checks the rest of the node
against a dataclass schema, so a typo, a wrong type or an impossible value fails before any work with a message
naming the full key (``reasoning.hiden``), and returns the typed config, which keeps its ``name``.
:meth:`Registry.build` is the one way from a validated config to its implementation: ``target(cfg=config,
**kwargs)``. Implementations are given as ``"module:attribute"`` strings and imported only when built: validating a
config never imports torch, so it takes well under a second.

The schemas are also Hydra's: :meth:`Registry.store_schemas` puts each one in Hydra's ConfigStore as
``schema/<group>/<name>``, and ``conf/<group>/<name>.yaml`` extends it (``defaults: [/schema/<group>/<name>@_here_]``),
naming only what differs from the dataclass' defaults; every default is written once, in the dataclass.
"""

from __future__ import annotations

import dataclasses
import importlib
from dataclasses import dataclass
from typing import Any

from omegaconf import DictConfig, OmegaConf, open_dict
from omegaconf.errors import OmegaConfBaseException


class ConfigError(ValueError):
    """A config that cannot run; the message starts with the offending key."""


@dataclass(frozen=True)
class Entry:
    schema: type
    target: str | None  # "package.module:attribute"; None for a spec that nothing builds (e.g. env clutter)


class Registry:
    def __init__(self, group: str) -> None:
        self.group = group
        self._entries: dict[str, Entry] = {}

    def register(self, name: str, schema: type, target: str | None = None) -> None:
        if name in self._entries:
            raise KeyError(f"{self.group} '{name}' is registered twice")
        self._entries[name] = Entry(schema, target)

    def names(self) -> list[str]:
        return sorted(self._entries)

    def get(self, name: str) -> Entry:
        if name not in self._entries:
            raise ConfigError(f"{self.group}.name: unknown {self.group} '{name}'; choose one of {self.names()}")
        return self._entries[name]

    def load(self, name: str) -> Any:
        """Import and return the implementation registered under ``name``."""
        target = self.get(name).target
        if target is None:
            raise ConfigError(f"{self.group}.name: '{name}' is a specification that nothing builds")
        module, _, attribute = target.partition(":")
        return getattr(importlib.import_module(module), attribute)

    def build(self, cfg: Any, **kwargs) -> Any:
        """The implementation of a validated config: ``target(cfg=cfg, **kwargs)``."""
        return self.load(cfg.name)(cfg=cfg, **kwargs)

    def validate(self, node: DictConfig | dict, path: str | None = None) -> Any:
        """Return the node as an instance of its schema carrying the node's ``name`` (an attribute, not a field:
        settings hashed into cache keys stay what they were), or raise :class:`ConfigError`."""
        path = path or self.group
        node = OmegaConf.create(node) if isinstance(node, dict) else node
        if node is None or "name" not in node:
            raise ConfigError(f"{path}.name: missing; choose one of {self.names()}")
        return named(typed(self.get(node.name).schema, node, path), node.name)

    def derive(self, cfg: Any, **changes) -> Any:
        """``dataclasses.replace(cfg, **changes)`` keeping the config's registry name (a variant of the run's env)."""
        return named(dataclasses.replace(cfg, **changes), cfg.name)

    def store_schemas(self) -> None:
        """Put every schema (its defaults, plus ``name``) in Hydra's ConfigStore as ``schema/<group>/<name>``."""
        from hydra.core.config_store import ConfigStore

        for name, entry in self._entries.items():
            node = _writable(OmegaConf.structured(entry.schema))
            with open_dict(node):
                node["name"] = name
            ConfigStore.instance().store(group=f"schema/{self.group}", name=name, node=node)


def typed(schema: type, node: DictConfig, path: str) -> Any:
    """``node`` (its interpolations resolved, without ``name``) as an instance of the dataclass ``schema``: the
    schema's defaults for what the node leaves out and its checks (``__post_init__``) on the merged values. Any
    problem is a :class:`ConfigError` naming the full key under ``path``."""
    try:
        body = {k: v for k, v in OmegaConf.to_container(node, resolve=True).items() if k != "name"}
        return OmegaConf.to_object(OmegaConf.merge(_writable(OmegaConf.structured(schema)), body))
    except OmegaConfBaseException as err:
        key = getattr(err, "full_key", None) or "?"
        key = key if key.startswith(f"{path}.") else f"{path}.{key}"  # a resolved interpolation names it in full
        raise ConfigError(f"{key}: {str(err).splitlines()[0]}") from None
    except (ValueError, TypeError) as err:  # raised by the schema's own checks (__post_init__)
        raise ConfigError(str(err)) from None


def named(config: Any, name: str) -> Any:
    """``config`` carrying its registry name as the attribute ``name`` (also on frozen dataclasses)."""
    object.__setattr__(config, "name", name)
    return config


def _writable(node: DictConfig) -> DictConfig:
    """Clear the read-only flag that frozen dataclass schemas put on every (nested) node, so values can merge in;
    the frozen instance built by ``to_object`` stays immutable."""
    node._set_flag("readonly", False)
    for key in node:
        child = node._get_node(key)
        if isinstance(child, DictConfig):
            _writable(child)
        else:
            child._set_flag("readonly", False)
    return node
