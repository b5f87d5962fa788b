"""Objects built from config nodes: ``hydra.utils.instantiate``, then checked to be the kind
the caller asked for, so a wrong ``_target_`` is one clear error naming the group.

The library takes the built objects (a sampler, a regressor) or their plain names; only
the application layer reads ``_target_``.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from rigmap.config_objects import instantiate_as
from rigmap.sampling.base import Sampler, SamplerInputError

__all__ = [
    "instantiate_as",
    "instantiate_sampler",
    "kernel_name",
    "plain",
    "sampler_from_node",
    "sampler_name",
]


def plain(config: Any) -> Any:
    """An OmegaConf node as plain, resolved dicts and lists; anything else as given."""
    from omegaconf import DictConfig, ListConfig, OmegaConf

    if isinstance(config, DictConfig | ListConfig):
        return OmegaConf.to_container(config, resolve=True)
    return config


def instantiate_sampler(config: Mapping[str, Any], **overrides: Any) -> Sampler:
    """The unfitted sampler a ``conf/sampler`` node describes (``_target_`` + hyper-parameters).

    ``overrides`` replace or add hyper-parameters (e.g. the rig's soft range).
    """
    return instantiate_as(
        {**dict(plain(config)), **overrides}, Sampler, "sampler", SamplerInputError
    )


def sampler_name(config: Mapping[str, Any]) -> str:
    """The name of the sampler a config node builds, read from its class (nothing is built)."""
    import hydra.utils

    target = config.get("_target_") if isinstance(config, Mapping) else None
    if target is None:
        raise SamplerInputError("sampler config: no _target_ (the sampler class)")
    cls = hydra.utils.get_class(str(target))
    if not (isinstance(cls, type) and issubclass(cls, Sampler)):
        raise SamplerInputError(f"sampler config: _target_ {target!r} is not a Sampler class")
    return cls.name


def sampler_from_node(name: str | None = None, **node: Any) -> Sampler:
    """The sampler a config node given as keywords builds (``sampler_from_node(**cfg.sampler)``),
    with ``name``, if given, checked against the class's name."""
    sampler = instantiate_sampler(node)
    if name is not None and sampler.name != name:
        raise ValueError(
            f"sampler config {name!r}: _target_ {node.get('_target_')!r} is the "
            f"{sampler.name!r} sampler"
        )
    return sampler


def kernel_name(kernel_config: Mapping[str, Any]) -> str:
    """The kernel's label in model ids (``multiquadric``, ``multiquadric_plus_linear`` …)."""
    import hydra.utils

    return str(hydra.utils.instantiate(dict(kernel_config)).label)
